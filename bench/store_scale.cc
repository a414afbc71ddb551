// Issue 4's storage benchmarks against the real bgkmapd binary (scripts/bench-storage.sh):
//
//  restart  A store of ~10^8 known cells, made of copies of the real Ouster street map written
//           straight through the storage API, is opened by bgkmapd; measured: time from process
//           start to the first answered point query and region query, and the RSS then.
//  bounded  bgkmapd with storage.max_memory_mb maps the real street scans at many places (a map
//           several times the bound), then answers a region query at every place; measured:
//           the server's peak RSS (sampled from /proc) against the bound, with the same run
//           unbounded for comparison.
//  info     bgkmapd on a copy of a store of ~10^7 known cells while 4 robots stream the real
//           scans at new places; measured: the ingest rate with a client calling Info at 20 Hz
//           and a GET /metrics at 1 Hz, against the same run without them, and Info's latency.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/storage/tile_store.h"
#include "percentile.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "store_scale: %s\n", what.c_str());
  std::exit(1);
}

std::vector<io::Scan> StreetScans(const std::string& dir) {
  Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
  if (!seq.ok()) Die(seq.status().ToString());
  std::vector<io::Scan> scans;
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> scan = seq->Read(k);
    if (!scan.ok()) Die(scan.status().ToString());
    scans.push_back(std::move(scan).value());
  }
  return scans;
}

// A bgkmapd child process; SIGTERM and reaped on destruction.
class Server {
 public:
  Server(const std::string& binary, const std::vector<std::string>& args) {
    pid_ = fork();
    if (pid_ == 0) {
      std::vector<char*> argv;
      argv.push_back(const_cast<char*>(binary.c_str()));
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      // BGKMAP_BENCH_SERVER_LOG: where the server's log goes (default: nowhere).
      const char* log = std::getenv("BGKMAP_BENCH_SERVER_LOG");
      const int out = open(log != nullptr ? log : "/dev/null", O_WRONLY | O_CREAT | O_APPEND, 0644);
      dup2(out, STDOUT_FILENO);
      dup2(out, STDERR_FILENO);
      execv(binary.c_str(), argv.data());
      _exit(127);
    }
  }
  ~Server() { Stop(); }
  pid_t pid() const { return pid_; }
  // Dies if the child has exited: a server that found its port taken exits at once, and the
  // benchmark would otherwise measure whatever else answers on that port.
  void DieUnlessRunning(int port) {
    int status = 0;
    if (pid_ > 0 && waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = 0;
      Die("bgkmapd exited (status " + std::to_string(status) + ") instead of serving on port " +
          std::to_string(port) + ": is another process listening there? (--port)");
    }
  }
  double Stop() {
    if (pid_ <= 0) return 0;
    const auto t0 = Clock::now();
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = 0;
    return Seconds(t0);
  }
  // VmRSS or VmHWM of the process, bytes.
  uint64_t Memory(const std::string& field) const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind(field + ":", 0) == 0) {
        std::istringstream s(line.substr(field.size() + 1));
        uint64_t kb = 0;
        s >> kb;
        return kb << 10;
      }
    }
    return 0;
  }

 private:
  pid_t pid_ = 0;
};

double Mb(uint64_t bytes) { return static_cast<double>(bytes) / (1 << 20); }

bool Listening(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0;
  close(fd);
  return ok;
}

// Before a server is started on `port`: nothing else may be listening there.
void DieIfPortTaken(int port) {
  if (Listening(port)) {
    Die("port " + std::to_string(port) + " is taken by another process (--port)");
  }
}

// ---- restart

// Writes copies of the street map's tiles on a grid of places until `cells` cells are known.
void BuildLargeStore(const std::string& dir, const std::vector<io::Scan>& street, double cells) {
  const MapParams params;
  std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(params)).value();
  for (const io::Scan& s : street) {
    if (!map->IntegrateScan(s.points, s.pose).ok()) Die("street scan rejected");
  }
  std::vector<std::pair<TileKey, const Tile*>> tiles;
  TileKey lo{INT32_MAX, INT32_MAX}, hi{INT32_MIN, INT32_MIN};
  map->ForEachTile([&](TileKey k, const Tile& t) {
    tiles.emplace_back(k, &t);
    lo = {std::min(lo.x, k.x), std::min(lo.y, k.y)};
    hi = {std::max(hi.x, k.x), std::max(hi.y, k.y)};
  });
  const int64_t per_copy = map->CountKnownCells();
  const int copies = static_cast<int>(std::ceil(cells / static_cast<double>(per_copy)));
  const int span_x = hi.x - lo.x + 2, span_y = hi.y - lo.y + 2;
  const int columns = static_cast<int>(std::ceil(std::sqrt(copies)));
  std::printf("writing %d copies of the street map (%zu tiles, %lld known cells each) to %s\n",
              copies, tiles.size(), static_cast<long long>(per_copy), dir.c_str());
  storage::StoreOptions options;
  Result<std::unique_ptr<storage::TileStore>> store =
      storage::TileStore::Open(dir, options, params);
  if (!store.ok()) Die(store.status().ToString());
  const auto t0 = Clock::now();
  std::vector<Tile> shifted;
  for (int c = 0; c < copies; ++c) {
    std::vector<storage::TileUpdate> updates;
    std::vector<std::unique_ptr<Tile>> owned;
    for (const auto& [k, t] : tiles) {
      owned.push_back(std::make_unique<Tile>(*t));
      owned.back()->set_version(1);
      updates.push_back(
          {{k.x + (c % columns) * span_x, k.y + (c / columns) * span_y}, owned.back().get()});
    }
    if (Status s = (*store)->Checkpoint(1, updates); !s.ok()) Die(s.ToString());
  }
  if (Status s = (*store)->Compact(); !s.ok()) Die(s.ToString());
  const storage::DiskUsage usage = (*store)->Usage();
  const double known = static_cast<double>(per_copy) * copies;
  std::printf(
      "store: %.3g known cells, %.1f MB on disk (%.1f bytes/known cell), written in %.1f s\n",
      known, Mb(usage.total_bytes), usage.total_bytes / known, Seconds(t0));
}

int RunRestart(const std::string& bgkmapd, const std::string& dir, const std::string& street_dir,
               double cells, int port, int trials) {
  if (!fs::exists(fs::path(dir) / "CURRENT")) BuildLargeStore(dir, StreetScans(street_dir), cells);
  const std::string target = "127.0.0.1:" + std::to_string(port);
  std::printf(
      "\n| trial | first point query | first 50x50 m region | RSS then | Info known cells |\n");
  std::printf("|---|---|---|---|---|\n");
  for (int trial = 1; trial <= trials; ++trial) {
    DieIfPortTaken(port);
    const auto t0 = Clock::now();
    Server server(bgkmapd, {"--listen", target, "--data-dir", dir, "--log-level", "warn"});
    // Poll the port with plain TCP connects: a gRPC channel that finds nothing listening backs
    // off for a second or more, which would be measured instead of the server.
    while (!Listening(port)) {
      if (Seconds(t0) > 120) Die("bgkmapd did not listen within 120 s");
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const double listening = Seconds(t0);
    server.DieUnlessRunning(port);
    Client client(target);
    // A point of the first copy: the query must load its tile from the store.
    const std::array<double, 2> point{0.5, 0.5};
    RpcResult<PointValues> first = client.QueryPoints(std::span(&point, 1));
    if (!first.ok()) Die(first.status().ToString());
    const double first_point = Seconds(t0);
    RpcResult<Raster> region = client.QueryRegion({{-25, -25, 25, 25}, {}, 1});
    if (!region.ok()) Die(region.status().ToString());
    const double first_region = Seconds(t0);
    const uint64_t rss = server.Memory("VmRSS");
    RpcResult<MapInfo> info = client.Info();
    if (!info.ok()) Die(info.status().ToString());
    std::printf("| %d | %.3f s | %.3f s | %.3f s | %.0f MB | %.4g |\n", trial, listening,
                first_point, first_region, Mb(rss), static_cast<double>(info->known_cells));
    std::fflush(stdout);
  }
  return 0;
}

// ---- bounded

int RunBounded(const std::string& bgkmapd, const std::string& street_dir, int sites,
               uint64_t bound_mb, int port) {
  const std::vector<io::Scan> street = StreetScans(street_dir);
  const std::string dir =
      (fs::temp_directory_path() / ("bgkmap_bounded_bench_" + std::to_string(getpid()))).string();
  fs::remove_all(dir);
  const std::string target = "127.0.0.1:" + std::to_string(port);
  DieIfPortTaken(port);
  Server server(bgkmapd, {"--listen", target, "--data-dir", dir, "--log-level", "warn", "--set",
                          "server.max_message_bytes=134217728", "--set",
                          "storage.max_memory_mb=" + std::to_string(bound_mb)});
  Client client(target);
  for (int i = 0; i < 2000 && !client.Info().ok(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  server.DieUnlessRunning(port);
  std::atomic<bool> done{false};
  std::atomic<uint64_t> peak{0};
  std::thread sampler([&] {
    while (!done.load()) {
      peak.store(std::max(peak.load(), server.Memory("VmRSS")));
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  const int columns = static_cast<int>(std::ceil(std::sqrt(sites)));
  auto site_origin = [&](int site) {
    return std::array<double, 2>{(site % columns) * 200.0, (site / columns) * 200.0};
  };
  const auto t0 = Clock::now();
  uint64_t sequence = 0;
  for (int site = 0; site < sites; ++site) {
    std::vector<ScanData> batch;
    for (const io::Scan& s : street) {
      Pose pose = s.pose;
      pose.translation.x() += site_origin(site)[0];
      pose.translation.y() += site_origin(site)[1];
      ScanData d;
      d.robot_id = "tour";
      d.sequence = ++sequence;
      d.pose = ScanPose::FromPose(pose);
      d.points = s.points;
      batch.push_back(d);
    }
    RpcResult<std::vector<ScanAck>> acks = client.IngestAll(batch);
    if (!acks.ok()) Die(acks.status().ToString());
  }
  const double ingest_s = Seconds(t0);
  const uint64_t peak_ingest = peak.load();
  const auto q0 = Clock::now();
  for (int site = 0; site < sites; ++site) {
    const auto [x, y] = site_origin(site);
    RpcResult<Raster> r = client.QueryRegion({{x - 25, y - 25, x + 25, y + 25}, {}, 1});
    if (!r.ok()) Die(r.status().ToString());
  }
  const double query_s = Seconds(q0);
  RpcResult<MapInfo> info = client.Info();
  if (!info.ok()) Die(info.status().ToString());
  done.store(true);
  sampler.join();
  if (std::getenv("BGKMAP_BENCH_PAUSE") != nullptr) {
    std::printf("server pid %d; press enter\n", static_cast<int>(server.pid()));
    std::getchar();
  }
  const uint64_t tile_bytes = sizeof(Tile) + static_cast<uint64_t>(info->params.tile_size) *
                                                 info->params.tile_size * Tile::kBytesPerCell;
  const uint64_t map_bytes = info->tile_count * tile_bytes;
  const StorageInfo& st = *info->storage;
  std::printf(
      "| %s | %d | %.0f MB | %.0f MB | %.0f MB | %.0f MB | %.1f s | %.2f s | %llu | %llu |\n",
      bound_mb == 0 ? "none" : (std::to_string(bound_mb) + " MB").c_str(), sites, Mb(map_bytes),
      Mb(peak_ingest), Mb(peak.load()), Mb(st.resident_bytes), ingest_s, query_s,
      static_cast<unsigned long long>(st.tiles_evicted),
      static_cast<unsigned long long>(st.tiles_loaded));
  server.Stop();
  fs::remove_all(dir);
  return 0;
}

// ---- info

// One GET of `path` from 127.0.0.1:port over a fresh connection; false on any failure.
bool HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bool ok = connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0;
  const std::string request = "GET " + path + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  ok = ok && write(fd, request.data(), request.size()) == static_cast<ssize_t>(request.size());
  std::string response;
  char buf[65536];
  for (ssize_t n; ok && (n = read(fd, buf, sizeof(buf))) > 0;) response.append(buf, n);
  close(fd);
  return ok && response.rfind("HTTP/1.1 200", 0) == 0;
}

// `with_readers`: a client calls Info at 20 Hz and scrapes /metrics at 1 Hz meanwhile.
int RunInfo(const std::string& bgkmapd, const std::string& store, const std::string& street_dir,
            double cells, int port, double seconds, bool with_readers, int robot_nice,
            double robot_hz) {
  const std::vector<io::Scan> street = StreetScans(street_dir);
  if (!fs::exists(fs::path(store) / "CURRENT")) BuildLargeStore(store, street, cells);
  // Each run starts from the same map: a copy of the store.
  const std::string dir =
      (fs::temp_directory_path() / ("bgkmap_info_bench_" + std::to_string(getpid()))).string();
  fs::remove_all(dir);
  fs::copy(store, dir, fs::copy_options::recursive);
  const std::string target = "127.0.0.1:" + std::to_string(port);
  const int metrics_port = port + 1;
  DieIfPortTaken(port);
  DieIfPortTaken(metrics_port);
  Server server(bgkmapd, {"--listen", target, "--data-dir", dir, "--log-level", "warn", "--metrics",
                          "127.0.0.1:" + std::to_string(metrics_port), "--set",
                          "storage.verify_on_start=false"});
  Client client(target);
  RpcResult<MapInfo> start_info = client.Info();
  for (int i = 0; i < 2000 && !start_info.ok(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    start_info = client.Info();
  }
  if (!start_info.ok()) Die(start_info.status().ToString());
  server.DieUnlessRunning(port);

  std::atomic<bool> stop{false};
  std::atomic<uint64_t> scans{0};
  std::vector<std::thread> robots;
  const auto t0 = Clock::now();
  for (int r = 0; r < 4; ++r) {
    robots.emplace_back([&, r] {
      // The robots stand in for machines elsewhere: their encoding must not take the server's
      // cores from it (`--robot-nice`).
      if (robot_nice != 0) setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), robot_nice);
      Client robot(target);
      uint64_t sequence = 0;
      // The street mapped at a new place each time, 100 m on from the last; robots 2 km apart.
      auto scan_at = [&](int place, const io::Scan& s) {
        Pose pose = s.pose;
        pose.translation.x() += 100.0 * place;
        pose.translation.y() += -5000.0 - 2000.0 * r;
        ScanData d;
        d.robot_id = "robot" + std::to_string(r);
        d.sequence = ++sequence;
        d.pose = ScanPose::FromPose(pose);
        d.points = s.points;
        return d;
      };
      if (robot_hz > 0) {
        // A lidar's pace: one scan every 1/hz s on one stream, acks read beside it.
        std::unique_ptr<IngestStream> stream = robot.OpenIngest();
        std::thread acks([&] {
          ScanAck ack;
          while (stream->ReadAck(&ack)) {
            if (Seconds(t0) < seconds) scans.fetch_add(1);
          }
        });
        auto next = Clock::now();
        for (int place = 0; Seconds(t0) < seconds; ++place) {
          for (const io::Scan& s : street) {
            if (!stream->Send(scan_at(place, s))) Die("ingest stream broke");
            next += std::chrono::microseconds(static_cast<int64_t>(1e6 / robot_hz));
            std::this_thread::sleep_until(next);
          }
        }
        stop.store(true);
        stream->CloseSend();
        acks.join();
        if (RpcStatus st = stream->Finish(); !st.ok()) Die(st.ToString());
        return;
      }
      for (int place = 0; !stop.load();) {
        std::vector<ScanData> batch;
        for (int k = 0; k < 4; ++k, ++place) {
          for (const io::Scan& s : street) batch.push_back(scan_at(place, s));
        }
        RpcResult<std::vector<ScanAck>> acks = robot.IngestAll(batch);
        if (!acks.ok()) Die(acks.status().ToString());
        if (Seconds(t0) < seconds) scans.fetch_add(acks->size());
        if (Seconds(t0) >= seconds) stop.store(true);
      }
    });
  }
  std::vector<double> info_ms, scrape_ms;
  std::thread readers;
  if (with_readers) {
    readers = std::thread([&] {
      Client reader(target);
      auto next = Clock::now();
      int tick = 0;
      while (!stop.load()) {
        const auto q0 = Clock::now();
        if (!reader.Info().ok()) Die("Info failed under load");
        info_ms.push_back(Seconds(q0) * 1e3);
        if (tick++ % 20 == 0) {
          const auto h0 = Clock::now();
          if (!HttpGet(metrics_port, "/metrics")) Die("GET /metrics failed under load");
          scrape_ms.push_back(Seconds(h0) * 1e3);
        }
        next += std::chrono::milliseconds(50);
        std::this_thread::sleep_until(next);
      }
    });
  }
  for (std::thread& t : robots) t.join();
  if (readers.joinable()) readers.join();
  RpcResult<MapInfo> end_info = client.Info();
  if (!end_info.ok()) Die(end_info.status().ToString());
  server.Stop();
  fs::remove_all(dir);
  std::printf(
      "| %s | %.3g | %.3g | %.1f | %zu | %.2f ms | %.2f ms | %.2f ms | %zu | %.1f ms |\n",
      (std::string(with_readers ? "Info 20 Hz + /metrics 1 Hz" : "none") +
       (robot_hz > 0 ? ", robots at " + std::to_string(static_cast<int>(robot_hz)) + " Hz" : ""))
          .c_str(),
      static_cast<double>(start_info->known_cells), static_cast<double>(end_info->known_cells),
      scans.load() / seconds, info_ms.size(), bench::Percentile(info_ms, 0.5),
      bench::Percentile(info_ms, 0.99),
      info_ms.empty() ? 0.0 : *std::max_element(info_ms.begin(), info_ms.end()), scrape_ms.size(),
      bench::Percentile(scrape_ms, 0.99));
  std::fflush(stdout);
  return 0;
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) {
  CLI::App app{"bgkmapd storage at scale: lazy restart and bounded memory"};
  std::string bgkmapd = "build/server/bgkmapd";
  std::string street = "../shared/data/ouster_os1_128_street";
  int port = 50581;
  app.add_option("--bgkmapd", bgkmapd, "bgkmapd binary")->capture_default_str();
  app.add_option("--street", street, "KITTI-like directory of the street scans")
      ->capture_default_str();
  app.add_option("--port", port, "loopback port for bgkmapd")->capture_default_str();
  app.require_subcommand(1);

  CLI::App* restart = app.add_subcommand("restart", "restart to first answer on a large store");
  std::string dir = "out/bench/store_1e8";
  double cells = 1e8;
  int trials = 3;
  restart->add_option("--data-dir", dir, "store directory (built if missing)")
      ->capture_default_str();
  restart->add_option("--cells", cells, "known cells to build")->capture_default_str();
  restart->add_option("--trials", trials, "restarts to time")->capture_default_str();

  CLI::App* bounded = app.add_subcommand("bounded", "build and query a map above the bound");
  int sites = 40;
  std::vector<uint64_t> bounds = {64, 0};
  bounded->add_option("--sites", sites, "places the street is mapped at")->capture_default_str();
  bounded->add_option("--bound-mb", bounds, "storage.max_memory_mb values (0: unbounded)")
      ->capture_default_str();
  CLI::App* info = app.add_subcommand("info", "ingest rate while Info and /metrics are polled");
  std::string info_store = "out/bench/store_1e7";
  double info_cells = 1e7, info_seconds = 20;
  int info_trials = 2, info_robot_nice = 0;
  double info_robot_hz = 0;
  info->add_option("--data-dir", info_store, "store directory (built if missing; copied per run)")
      ->capture_default_str();
  info->add_option("--cells", info_cells, "known cells to build")->capture_default_str();
  info->add_option("--seconds", info_seconds, "length of each run")->capture_default_str();
  info->add_option("--trials", info_trials, "pairs of runs (without, with readers)")
      ->capture_default_str();
  info->add_option("--robot-hz", info_robot_hz,
                   "scans per second each robot sends on one stream (0: as fast as acked)")
      ->capture_default_str();
  info->add_option("--robot-nice", info_robot_nice,
                   "nice value of the robots' threads (they stand in for other machines)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (restart->parsed()) return bgkmap::RunRestart(bgkmapd, dir, street, cells, port, trials);
  if (info->parsed()) {
    std::printf(
        "| readers | known cells at start | at end | ingest scans/s | Info calls | Info p50 | "
        "Info p99 | Info max | scrapes | scrape p99 |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
    for (int t = 0; t < info_trials; ++t) {
      for (bool readers : {false, true}) {
        if (int rc = bgkmap::RunInfo(bgkmapd, info_store, street, info_cells, port, info_seconds,
                                     readers, info_robot_nice, info_robot_hz);
            rc != 0) {
          return rc;
        }
      }
    }
    return 0;
  }
  std::printf(
      "| bound | places | map (tiles) | peak RSS ingest | peak RSS ingest+queries | "
      "tiles in memory at end | ingest | region queries | tiles evicted | tiles loaded |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (uint64_t b : bounds) {
    if (int rc = bgkmap::RunBounded(bgkmapd, street, sites, b, port); rc != 0) return rc;
  }
  return 0;
}
