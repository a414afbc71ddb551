// Per-scan update cost, split into the paper's three stages (Table 1): BGK elevation
// inference, traversability computation, BGK traversability inference.
//
//   build/bench/scan_update_benchmark --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/sim/ray_caster.h"
#include "street_world.h"

namespace bgkmap {
namespace {

struct Sequence {
  std::vector<std::vector<Point3f>> scans;
  std::vector<Pose> poses;
};

// Scans every metre along the street, like the paper's City run (1 m between scans).
const Sequence& Drive(const sim::BeamModel& beams, double sensor_height) {
  static std::map<std::string, Sequence> cache;
  Sequence& seq = cache[beams.name];
  if (!seq.scans.empty()) return seq;
  const bench::StreetWorld world;
  for (int i = 0; i < 24; ++i) {
    Pose pose;
    pose.translation = {1.0 * i, 0.0, world.SurfaceHeight(1.0 * i, 0.0) + sensor_height};
    sim::RayCastOptions opt;
    opt.seed = 1 + i;
    seq.scans.push_back(sim::SimulateScan(world, beams, pose, opt));
    seq.poses.push_back(pose);
  }
  return seq;
}

void RunScanUpdate(benchmark::State& state, const sim::BeamModel& beams, double kernel_length,
                   Method method, int tile_size = 64, Dynamics dynamics = Dynamics::kOn,
                   double half_life_s = 0) {
  const Sequence& seq = Drive(beams, 0.8);
  MapParams p;
  p.resolution = 0.1;
  p.kernel_length = kernel_length;
  p.robot_radius = 0.3;
  p.method = method;
  p.tile_size = tile_size;
  p.dynamics = dynamics;
  p.half_life_s = half_life_s;
  std::unique_ptr<TerrainMap> map;
  size_t next = 0;
  StageTimes sum;
  double points = 0, observed = 0, contradicted = 0, bytes_per_known = 0;
  for (auto _ : state) {
    if (next % seq.scans.size() == 0) {  // restart the drive on a fresh map, untimed
      state.PauseTiming();
      if (map) {  // memory after one complete 24 m drive
        bytes_per_known = static_cast<double>(map->TileMemoryBytes()) /
                          static_cast<double>(map->CountKnownCells());
      }
      map = std::move(TerrainMap::Create(p)).value();
      state.ResumeTiming();
    }
    const size_t k = next++ % seq.scans.size();
    // With forgetting, stamped at 10 Hz: every write tile is aged at every scan.
    const int64_t stamp = half_life_s > 0 ? static_cast<int64_t>(next) * 100'000'000 : 0;
    Result<ScanReport> r = map->IntegrateScan(seq.scans[k], seq.poses[k], false, stamp);
    benchmark::DoNotOptimize(r);
    sum.elevation += r->times.elevation;
    sum.features += r->times.features;
    sum.traversability += r->times.traversability;
    points += static_cast<double>(r->counts.input);
    observed += static_cast<double>(r->observed_cells);
    contradicted += static_cast<double>(r->contradicted_cells);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["points"] = points / n;
  state.counters["observed_cells"] = observed / n;
  state.counters["contradicted"] = contradicted / n;
  state.counters["elev_ms"] = 1e3 * sum.elevation / n;
  state.counters["feat_ms"] = 1e3 * sum.features / n;
  state.counters["trav_ms"] = 1e3 * sum.traversability / n;
  state.counters["bytes_per_known_cell"] = bytes_per_known;
  state.SetItemsProcessed(static_cast<int64_t>(points));
}

void BM_Vlp16(benchmark::State& s, Method m) { RunScanUpdate(s, sim::Vlp16(), 0.3, m); }
void BM_Hdl32e(benchmark::State& s, Method m) { RunScanUpdate(s, sim::Hdl32e(), 1.0, m); }
// The paper's accumulation (dynamics: off): the cost of following a changing world.
void BM_Vlp16Paper(benchmark::State& s, Method m) {
  RunScanUpdate(s, sim::Vlp16(), 0.3, m, 64, Dynamics::kOff);
}
void BM_Hdl32ePaper(benchmark::State& s, Method m) {
  RunScanUpdate(s, sim::Hdl32e(), 1.0, m, 64, Dynamics::kOff);
}
// Forgetting on (half_life_s 10, scans at 10 Hz): the cost of ageing the tiles each scan writes.
void BM_Vlp16Forget(benchmark::State& s, Method m) {
  RunScanUpdate(s, sim::Vlp16(), 0.3, m, 64, Dynamics::kOn, 10.0);
}
void BM_Hdl32eForget(benchmark::State& s, Method m) {
  RunScanUpdate(s, sim::Hdl32e(), 1.0, m, 64, Dynamics::kOn, 10.0);
}
BENCHMARK_CAPTURE(BM_Vlp16Forget, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32eForget, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16Paper, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32ePaper, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);

BENCHMARK_CAPTURE(BM_Vlp16, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32e, bgk_plus, Method::kBgkPlus)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16, baseline, Method::kBaseline)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16, one_step, Method::kOneStep)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16, bgk_obstacle, Method::kBgkObstacle)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32e, bgk_obstacle, Method::kBgkObstacle)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16, bgk_ll, Method::kBgkLocalLinear)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32e, bgk_ll, Method::kBgkLocalLinear)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16Paper, bgk_ll, Method::kBgkLocalLinear)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32ePaper, bgk_ll, Method::kBgkLocalLinear)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vlp16, bgk_trav, Method::kBgkTrav)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Hdl32e, bgk_trav, Method::kBgkTrav)->Unit(benchmark::kMillisecond);

// Memory per known cell against tile size: small tiles waste less on sparse far returns.
void BM_Vlp16TileSize(benchmark::State& s) {
  RunScanUpdate(s, sim::Vlp16(), 0.3, Method::kBgkPlus, static_cast<int>(s.range(0)));
}
BENCHMARK(BM_Vlp16TileSize)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// Region extraction (the server's share of a region query): 50 x 50 m at 0.1 m, all layers, over
// the map of one VLP-16 drive.
void BM_ExtractRaster50m(benchmark::State& state) {
  const Sequence& seq = Drive(sim::Vlp16(), 0.8);
  auto map = std::move(TerrainMap::Create(MapParams{})).value();
  for (size_t k = 0; k < seq.scans.size(); ++k)
    (void)map->IntegrateScan(seq.scans[k], seq.poses[k]);
  const CellBox box = map->geometry().BoxCovering(-13, -25, 37, 25);
  const std::vector<Layer> all = {Layer::kElevation,      Layer::kElevationVariance,
                                  Layer::kTraversability, Layer::kTraversabilityVariance,
                                  Layer::kState,          Layer::kElevationWeight};
  Raster r;
  for (auto _ : state) {
    r = ExtractRaster(*map, box, all);
    benchmark::DoNotOptimize(r);
  }
  state.counters["cells"] = static_cast<double>(box.cell_count());
  const std::vector<float>& weight = *r.Find(Layer::kElevationWeight);
  state.counters["known"] = static_cast<double>(
      std::count_if(weight.begin(), weight.end(), [](float w) { return !std::isnan(w); }));
}
BENCHMARK(BM_ExtractRaster50m)->Unit(benchmark::kMillisecond);

void BM_PrepareVlp16(benchmark::State& state) {
  const Sequence& seq = Drive(sim::Vlp16(), 0.8);
  const MapParams p;
  size_t k = 0;
  for (auto _ : state) {
    auto r = PrepareScan(p, seq.scans[k % seq.scans.size()], seq.poses[k % seq.scans.size()]);
    benchmark::DoNotOptimize(r);
    ++k;
  }
}
BENCHMARK(BM_PrepareVlp16)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace bgkmap

BENCHMARK_MAIN();
