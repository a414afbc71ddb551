// `bgkmap watch`: prints one JSON line per changed tile in a region, until --count updates,
// --duration seconds, or Ctrl-C.
#include <atomic>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>

#include "client_options.h"
#include "commands.h"

namespace bgkmap::cli {
namespace {

std::atomic<bool> g_interrupted{false};

struct WatchOptions {
  ServerTarget server;
  std::vector<double> bbox;
  int count = 0;        // 0: unlimited
  double duration = 0;  // seconds, 0: unlimited
  bool snapshot = false;
};

int RunWatch(const WatchOptions& o) {
  Result<MetricBox> box = ParseBox(o.bbox, "--bbox");
  if (!box.ok()) return Usage("watch", box.status().message());
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("watch", connected.status().message());
  Client& client = **connected;
  std::mutex mu;
  std::condition_variable cv;
  int seen = 0;
  auto sub = client.Watch({*box, {Layer::kState}, o.snapshot}, [&](const TileUpdate& u) {
    int64_t known = 0, traversable = 0;
    for (float s : u.raster.data[0]) {
      known += s != 0.0f;
      traversable += s == 1.0f;
    }
    const nlohmann::json line = {{"tile", {u.key.x, u.key.y}},
                                 {"tile_version", u.tile_version},
                                 {"map_version", u.map_version},
                                 {"known_cells", known},
                                 {"traversable_cells", traversable}};
    std::lock_guard<std::mutex> lock(mu);
    if (o.count > 0 && seen >= o.count) return;  // updates racing the cancel are not printed
    std::printf("%s\n", line.dump().c_str());
    std::fflush(stdout);
    ++seen;
    cv.notify_all();
  });
  std::signal(SIGINT, [](int) { g_interrupted = true; });
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(o.duration * 1000));
  {
    std::unique_lock<std::mutex> lock(mu);
    while (!g_interrupted && (o.count == 0 || seen < o.count) &&
           (o.duration <= 0 || std::chrono::steady_clock::now() < deadline)) {
      cv.wait_for(lock, std::chrono::milliseconds(100));
    }
  }
  sub->Cancel();
  const RpcStatus end = sub->Wait();
  if (!end.ok() && end.code() != RpcCode::kCancelled) return Fail("watch", end.ToString());
  return 0;
}

}  // namespace

void RegisterWatchCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<WatchOptions>();
  CLI::App* cmd = app.add_subcommand("watch", "Stream changed tiles of a region (JSON lines)");
  AddServerOption(cmd, o->server);
  cmd->add_option("--bbox", o->bbox, "xmin,ymin,xmax,ymax in metres")
      ->delimiter(',')
      ->expected(4)
      ->required();
  cmd->add_option("--count", o->count, "Stop after this many updates");
  cmd->add_option("--duration", o->duration, "Stop after this many seconds");
  cmd->add_flag("--snapshot", o->snapshot, "Start with the current tiles of the region");
  cmd->callback([o, &exit_code] { exit_code = RunWatch(*o); });
}

}  // namespace bgkmap::cli
