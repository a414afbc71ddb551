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
#include "bgkmap/server/heap_policy.h"
#include "bgkmap/server/log_safe.h"
#include "bgkmap/server/map_server.h"
#include "bgkmap/server/server_config.h"

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

// The command line, as given.
struct CommandLine {
  std::string config_path;
  std::string listen;
  int worker_threads = -1;
  int query_threads = -1;
  std::string log_level;
  std::string data_dir;
  std::string metrics;
  bool metrics_set = false;
  std::string foxglove;
  bool foxglove_set = false;
  std::vector<std::string> overrides;
  bool print_config = false;
};

void DeclareOptions(CLI::App& app, CommandLine& cmd, CLI::Option** metrics_flag,
                    CLI::Option** foxglove_flag) {
  app.add_option("-c,--config", cmd.config_path,
                 "YAML config: engine keys at the top level, server keys under 'server:'")
      ->check(CLI::ExistingFile);
  app.add_option("-l,--listen", cmd.listen,
                 "Listen address host:port (overrides server.listen_address)");
  *metrics_flag =
      app.add_option("--http,--metrics", cmd.metrics,
                     "Serve HTTP on host:port: the live web map at /, GET /metrics (Prometheus); "
                     "\"\" = off (overrides server.metrics_address; --metrics is its old name)");
  *foxglove_flag =
      app.add_option("--foxglove", cmd.foxglove,
                     "Serve the Foxglove WebSocket protocol on host:port: the map around "
                     "server.foxglove.region, the robots' poses and last scans (docs/foxglove.md); "
                     "\"\" = off (overrides server.foxglove.address)");
  app.add_option("--worker-threads", cmd.worker_threads, "Ingest worker threads (0 = all cores)");
  app.add_option("--query-threads", cmd.query_threads, "Query worker threads (0 = all cores)");
  app.add_option("--log-level", cmd.log_level, "trace|debug|info|warn|error|off");
  app.add_option("--data-dir", cmd.data_dir,
                 "Persist the map in this directory (overrides storage.data_dir)");
  app.add_option("--set", cmd.overrides,
                 "Override a key: KEY=VALUE for engine keys, server.KEY=VALUE for server keys "
                 "(repeatable)");
  app.add_flag("--print-config", cmd.print_config, "Print the effective configuration and exit");
  app.set_version_flag("--version", std::string("bgkmapd ") + BGKMAP_VERSION);
}

// The flags as config overrides, then the --set ones (later ones win).
std::vector<std::string> FlagOverrides(const CommandLine& cmd) {
  std::vector<std::string> out;
  // String flags are quoted, so that "" (off), "[::1]:9100" or a path with '#' read as the
  // strings they are rather than as YAML.
  auto set_string = [&out](const std::string& key, const std::string& value) {
    YAML::Emitter quoted;
    quoted << YAML::DoubleQuoted << value;
    out.push_back(key + "=" + std::string(quoted.c_str()));
  };
  if (!cmd.listen.empty()) set_string("server.listen_address", cmd.listen);
  if (cmd.metrics_set) set_string("server.metrics_address", cmd.metrics);
  if (cmd.foxglove_set) set_string("server.foxglove.address", cmd.foxglove);
  if (cmd.worker_threads >= 0) {
    out.push_back("server.worker_threads=" + std::to_string(cmd.worker_threads));
  }
  if (cmd.query_threads >= 0) {
    out.push_back("server.query_threads=" + std::to_string(cmd.query_threads));
  }
  if (!cmd.log_level.empty()) set_string("server.log_level", cmd.log_level);
  if (!cmd.data_dir.empty()) set_string("storage.data_dir", cmd.data_dir);
  out.insert(out.end(), cmd.overrides.begin(), cmd.overrides.end());
  return out;
}

// The config file, then the flags. The error is the message to print (exit 2).
bgkmap::Result<bgkmap::ServerConfig> LoadConfig(const CommandLine& cmd) {
  bgkmap::ServerConfig config;
  if (!cmd.config_path.empty()) {
    bgkmap::Result<YAML::Node> doc = bgkmap::LoadYamlFile(cmd.config_path);
    if (!doc.ok()) return doc.status();
    bgkmap::Result<bgkmap::ServerConfig> parsed = bgkmap::ServerConfigFromYaml(*doc);
    if (!parsed.ok()) {
      return bgkmap::Status::InvalidArgument(cmd.config_path + ": " + parsed.status().message());
    }
    config = *parsed;
  }
  for (const std::string& o : FlagOverrides(cmd)) {
    if (bgkmap::Status s = bgkmap::ApplyConfigOverride(config, o); !s.ok()) return s;
  }
  return config;
}

// Runs the server until SIGINT or SIGTERM (SIGHUP re-reads the tokens); the exit code.
int Serve(const bgkmap::ServerConfig& config) {
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bgkmapd: BGK terrain traversability map server (gRPC bgkmap.v1.MapService)"};
  CommandLine cmd;
  CLI::Option* metrics_flag = nullptr;
  CLI::Option* foxglove_flag = nullptr;
  DeclareOptions(app, cmd, &metrics_flag, &foxglove_flag);
  CLI11_PARSE(app, argc, argv);
  cmd.metrics_set = metrics_flag->count() > 0;
  cmd.foxglove_set = foxglove_flag->count() > 0;

  bgkmap::Result<bgkmap::ServerConfig> config = LoadConfig(cmd);
  if (!config.ok()) return Fail(config.status().message());
  if (cmd.print_config) {
    std::cout << bgkmap::ServerConfigToYaml(*config);
    return 0;
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("bgkmapd"));
  spdlog::set_level(spdlog::level::from_str(config->log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e%z %^%l%$ %v");
  bgkmap::KeepLargeAllocationsInHeap();
  bgkmap::LimitHeapArenas(config->malloc_arenas);
  return Serve(*config);
}
