// bgkmapd: the bgkmap terrain map server.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <csignal>
#include <functional>
#include <iostream>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/server/map_server.h"
#include "bgkmap/server/server_config.h"
#include "log_safe.h"

namespace {

int Fail(const std::string& message) {
  std::cerr << "bgkmapd: " << message << "\n";
  return 2;
}

std::string RobotsLine(const bgkmap::ServerReport& report) {
  std::ostringstream s;
  for (size_t i = 0; i < report.robots.size(); ++i) {
    if (i > 0) s << ",";
    // Ids recovered from a store written before ids were checked may hold control characters.
    s << bgkmap::LogSafe(report.robots[i].robot_id, 128) << ":" << report.robots[i].last_sequence;
  }
  return s.str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bgkmapd: BGK terrain traversability map server (gRPC bgkmap.v1.MapService)"};
  std::string config_path;
  std::string listen;
  int worker_threads = -1;
  int query_threads = -1;
  std::string log_level;
  std::string data_dir;
  std::string metrics;
  std::vector<std::string> overrides;
  bool print_config = false;
  app.add_option("-c,--config", config_path,
                 "YAML config: engine keys at the top level, server keys under 'server:'")
      ->check(CLI::ExistingFile);
  app.add_option("-l,--listen", listen,
                 "Listen address host:port (overrides server.listen_address)");
  CLI::Option* metrics_flag =
      app.add_option("--metrics,--http", metrics,
                     "Serve HTTP on host:port: GET /metrics (Prometheus) and the live web map at "
                     "/; \"\" = off (overrides server.metrics_address)");
  app.add_option("--worker-threads", worker_threads, "Ingest worker threads (0 = all cores)");
  app.add_option("--query-threads", query_threads, "Query worker threads (0 = all cores)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off");
  app.add_option("--data-dir", data_dir,
                 "Persist the map in this directory (overrides storage.data_dir)");
  app.add_option("--set", overrides,
                 "Override a key: KEY=VALUE for engine keys, server.KEY=VALUE for server keys "
                 "(repeatable)");
  app.add_flag("--print-config", print_config, "Print the effective configuration and exit");
  app.set_version_flag("--version", std::string("bgkmapd ") + BGKMAP_VERSION);
  CLI11_PARSE(app, argc, argv);

  bgkmap::ServerConfig config;
  if (!config_path.empty()) {
    bgkmap::Result<YAML::Node> doc = bgkmap::LoadYamlFile(config_path);
    if (!doc.ok()) return Fail(doc.status().message());
    bgkmap::Result<bgkmap::ServerConfig> parsed = bgkmap::ServerConfigFromYaml(*doc);
    if (!parsed.ok()) return Fail(config_path + ": " + parsed.status().message());
    config = *parsed;
  }
  std::vector<std::string> flag_overrides;
  // String flags are quoted, so that "" (off), "[::1]:9100" or a path with '#' read as the
  // strings they are rather than as YAML.
  auto set_string = [&flag_overrides](const std::string& key, const std::string& value) {
    YAML::Emitter quoted;
    quoted << YAML::DoubleQuoted << value;
    flag_overrides.push_back(key + "=" + std::string(quoted.c_str()));
  };
  if (!listen.empty()) set_string("server.listen_address", listen);
  if (metrics_flag->count() > 0) set_string("server.metrics_address", metrics);
  if (worker_threads >= 0) {
    flag_overrides.push_back("server.worker_threads=" + std::to_string(worker_threads));
  }
  if (query_threads >= 0) {
    flag_overrides.push_back("server.query_threads=" + std::to_string(query_threads));
  }
  if (!log_level.empty()) set_string("server.log_level", log_level);
  if (!data_dir.empty()) set_string("storage.data_dir", data_dir);
  flag_overrides.insert(flag_overrides.end(), overrides.begin(), overrides.end());
  for (const std::string& o : flag_overrides) {
    if (bgkmap::Status s = bgkmap::ApplyConfigOverride(config, o); !s.ok()) {
      return Fail(s.message());
    }
  }
  if (print_config) {
    std::cout << bgkmap::ServerConfigToYaml(config);
    return 0;
  }

  const spdlog::level::level_enum level = spdlog::level::from_str(config.log_level);
  spdlog::set_default_logger(spdlog::stderr_color_mt("bgkmapd"));
  spdlog::set_level(level);
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e%z %^%l%$ %v");

  bgkmap::KeepLargeAllocationsInHeap();
  // Signals are caught before the server starts: a SIGTERM right after "event=listening" (or
  // during a long recovery) must still shut down gracefully, with the last checkpoint.
  boost::asio::io_context io;
  boost::asio::signal_set signals(io, SIGINT, SIGTERM);
  boost::asio::signal_set hangup(io, SIGHUP);  // re-read server.auth.tokens_file
  bgkmap::Result<std::unique_ptr<bgkmap::MapServer>> server = bgkmap::MapServer::Start(config);
  if (!server.ok()) {
    spdlog::error("event=start_failed reason=\"{}\"", server.status().message());
    return 1;
  }
  std::function<void()> wait_hangup = [&] {
    hangup.async_wait([&](const boost::system::error_code& ec, int) {
      if (ec) return;
      spdlog::info("event=signal signal=SIGHUP");
      (void)(*server)->ReloadTokens();  // logs the outcome; a bad file keeps the old tokens
      wait_hangup();
    });
  };
  wait_hangup();
  signals.async_wait([&](const boost::system::error_code& ec, int signal) {
    if (ec) return;
    hangup.cancel();
    spdlog::info("event=signal signal={}", signal == SIGINT ? "SIGINT" : "SIGTERM");
    (*server)->Shutdown();
  });
  io.run();

  const bgkmap::ServerReport report = (*server)->Report();
  spdlog::info("event=final_map map_version={} scans_applied={} tiles={} known_cells={} robots={}",
               report.map_version, report.scans_applied, report.tile_count, report.known_cells,
               RobotsLine(report));
  server->reset();
  spdlog::info("event=exit code=0");
  return 0;
}
