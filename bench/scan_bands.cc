// One scan's integration in bands against whole (core/scan_bands.h; server.scan_bands), with the
// cores free: every scan of a KITTI-like drive is read and prepared first, then integrated in
// turn into a fresh map, whole on one thread or cut into N bands on N threads (the server's
// RunSharingWithPool is replaced by plain threads: nothing else runs). Rounds alternate the two;
// prints the median per-scan wall time of each, the CPU, and whether the maps are the same bits.
//   scan_bands <drive> [--config robot.yaml] [--bands 2] [--rounds 5]
#include "bgkmap/core/scan_bands.h"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/io/kitti_sequence.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "scan_bands: %s\n", what.c_str());
  std::exit(1);
}

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

std::vector<PreparedScan> PrepareDrive(const std::string& dir, const MapParams& params) {
  Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
  if (!seq.ok()) Die(seq.status().message());
  std::vector<PreparedScan> scans;
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> s = seq->Read(k);
    if (!s.ok()) Die(s.status().message());
    Result<PreparedScan> p = PrepareScan(params, s->points, s->pose);
    if (!p.ok()) Die(p.status().message());
    scans.push_back(std::move(p).value());
  }
  return scans;
}

// Runs the first task here and each other on a thread of its own.
void OnThreads(std::span<const std::function<void()>> tasks) {
  std::vector<std::thread> others;
  for (size_t i = 1; i < tasks.size(); ++i) others.emplace_back(tasks[i]);
  if (!tasks.empty()) tasks[0]();
  for (std::thread& t : others) t.join();
}

struct Run {
  double wall_s = 0, cpu_s = 0;
  std::unique_ptr<TerrainMap> map;
};

Run Integrate(const MapParams& params, const std::vector<PreparedScan>& scans, int bands) {
  Run run;
  run.map = std::move(TerrainMap::Create(params)).value();
  const double cpu0 = CpuSeconds();
  const auto t0 = Clock::now();
  for (size_t k = 0; k < scans.size(); ++k) {
    const TileWindow window = run.map->MakeWindow(scans[k]);
    if (bands <= 1) {
      run.map->Integrate(scans[k], window, k + 1);
      continue;
    }
    const std::vector<TileBand> cut = CutScansIntoBands(params, {&scans[k], 1}, bands);
    if (!IntegrateInBands(*run.map, scans[k], window, cut, k + 1, OnThreads)) {
      Die("a band's tile is missing from the window");
    }
  }
  run.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  run.cpu_s = CpuSeconds() - cpu0;
  return run;
}

bool SameMaps(const TerrainMap& a, const TerrainMap& b) {
  bool same = a.tile_count() == b.tile_count();
  a.ForEachTile([&](TileKey key, const Tile& t) {
    const Tile* o = b.FindTile(key);
    same = same && o != nullptr && t == *o && t.version() == o->version();
  });
  return same;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int Main(int argc, char** argv) {
  if (argc < 2) Die("usage: scan_bands <drive> [--config robot.yaml] [--bands 2] [--rounds 5]");
  std::string config;
  int bands = 2, rounds = 5;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--config") {
      config = argv[i + 1];
    } else if (flag == "--bands") {
      bands = std::atoi(argv[i + 1]);
    } else if (flag == "--rounds") {
      rounds = std::atoi(argv[i + 1]);
    } else {
      Die("unknown flag " + flag);
    }
  }
  Result<MapParams> params = LoadMapParamsFileOrDefaults(config);
  if (!params.ok()) Die(params.status().message());
  const std::vector<PreparedScan> scans = PrepareDrive(argv[1], *params);
  const double n = static_cast<double>(scans.size());
  std::vector<double> whole_ms, banded_ms, whole_cpu, banded_cpu;
  bool same = true;
  for (int r = 0; r < rounds; ++r) {
    Run w = Integrate(*params, scans, 1);
    Run b = Integrate(*params, scans, bands);
    same = same && SameMaps(*w.map, *b.map);
    whole_ms.push_back(1e3 * w.wall_s / n);
    banded_ms.push_back(1e3 * b.wall_s / n);
    whole_cpu.push_back(1e3 * w.cpu_s / n);
    banded_cpu.push_back(1e3 * b.cpu_s / n);
  }
  std::printf(
      "%zu scans, %d rounds: whole %.2f ms/scan (CPU %.2f), %d bands %.2f ms/scan (CPU %.2f)"
      ", %.2fx; maps %s\n",
      scans.size(), rounds, Median(whole_ms), Median(whole_cpu), bands, Median(banded_ms),
      Median(banded_cpu), Median(whole_ms) / Median(banded_ms), same ? "the same bits" : "DIFFER");
  return same ? 0 : 1;
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) { return bgkmap::Main(argc, argv); }
