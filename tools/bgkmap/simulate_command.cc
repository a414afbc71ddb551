// `bgkmap simulate`: renders one of the paper's simulated experiments (city, aerial) into a
// KITTI-like sequence plus its ground truth (docs/results.md explains the worlds).
//   <out>/velodyne/NNNNNN.bin, <out>/poses.txt   the mapping scans, sensor frame
//   <out>/odometry_poses.txt                     with --drift: the same scans' poses as a
//                                                drifting odometry would report them
//   <out>/ground_truth.tif                       true elevation, traversability, state
//   <out>/scenario.json                          what was simulated
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/io/esri_ascii_grid.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/progress_bar.h"
#include "bgkmap/sim/ground_truth.h"
#include "bgkmap/sim/odometry_drift.h"
#include "bgkmap/sim/ray_caster.h"
#include "bgkmap/sim/scenario.h"
#include "commands.h"
#include "json_output.h"

namespace bgkmap::cli {
namespace {

struct SimulateOptions {
  std::string world;
  std::string out;
  std::string config;
  std::string dem;
  double truth_spacing = 0;  // 0 = the scenario's default
  double length = 210.0;     // city only
  int grid = 13;             // aerial only
  int threads = 2;
  bool truth = true;  // false: the mapping scans only (e.g. a cloud for bgkmap regress)
  double drift = 0;   // > 0: also odometry_poses.txt (sim/odometry_drift.h)
};

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap simulate: %s\n", msg.c_str());
  return kExitFailure;
}

// A bad command line: the same line, exit code kExitUsage.
int Usage(const std::string& msg) {
  Fail(msg);
  return kExitUsage;
}

// Runs fn(k) for k in [0, n) on `threads` workers; fn gets the worker index too.
template <typename Fn>
void ParallelFor(size_t n, int threads, io::ProgressBar& progress, Fn fn) {
  std::atomic<size_t> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (size_t k = next++; k < n; k = next++) {
        fn(k, t);
        progress.Add();
      }
    });
  }
  for (std::thread& th : pool) th.join();
}

int RunSimulate(const SimulateOptions& o) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  MapParams params = *loaded;
  if (o.threads < 1) return Usage("--threads must be at least 1");

  sim::Scenario scenario;
  double origin_x = 0, origin_y = 0;  // world frame = georeferenced frame minus this
  if (o.world == "city") {
    if (!(o.length > 0)) return Usage("--length must be > 0");
    scenario = sim::MakeCityScenario(o.length, 1.0, o.truth_spacing > 0 ? o.truth_spacing : 0.1);
  } else if (o.world == "aerial") {
    if (o.dem.empty()) return Usage("aerial needs --dem (an ESRI ASCII grid)");
    if (o.grid < 2) return Usage("--grid must be at least 2");
    Result<io::EsriAsciiGrid> dem = io::ReadEsriAsciiGrid(o.dem);
    if (!dem.ok()) return Fail(dem.status().message());
    origin_x = dem->x0;
    origin_y = dem->y0;
    sim::HeightGrid grid{dem->cols, dem->rows, 0.0, 0.0, dem->cellsize, std::move(dem->values)};
    scenario = sim::MakeAerialScenario(std::move(grid), o.grid, 10.0,
                                       o.truth_spacing > 0 ? o.truth_spacing : 2.5);
  } else {
    return Usage("unknown world '" + o.world + "' (expected city or aerial)");
  }

  std::error_code ec;
  fs::create_directories(fs::path(o.out) / "velodyne", ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());
  const std::string poses_path = (fs::path(o.out) / "poses.txt").string();
  fs::remove(poses_path, ec);

  // Mapping scans: one file each, poses appended in order afterwards.
  std::mutex error_mu;
  std::string error;
  const size_t n = scenario.mapping_poses.size();
  {
    io::ProgressBar progress("simulating " + scenario.name, n, "scans");
    ParallelFor(n, o.threads, progress, [&](size_t k, int) {
      sim::RayCastOptions rc;
      rc.seed = static_cast<unsigned>(k + 1);
      const auto pts =
          sim::SimulateScan(*scenario.world, scenario.beams, scenario.mapping_poses[k], rc);
      const std::string path = (fs::path(o.out) / "velodyne" / io::KittiScanFileName(k)).string();
      if (Status s = io::WriteKittiScan(path, pts); !s.ok()) {
        std::lock_guard lock(error_mu);
        error = s.message();
      }
    });
  }
  if (!error.empty()) return Fail(error);
  for (const Pose& pose : scenario.mapping_poses) {
    if (Status s = io::AppendPose(poses_path, pose); !s.ok()) return Fail(s.message());
  }
  if (o.drift > 0) {
    const std::string odometry_path = (fs::path(o.out) / "odometry_poses.txt").string();
    fs::remove(odometry_path, ec);
    sim::DriftOptions drift;
    drift.translation_per_m = o.drift;
    drift.yaw_per_m = o.drift / 5.0;
    for (const Pose& pose : sim::DriftedOdometry(scenario.mapping_poses, drift)) {
      if (Status s = io::AppendPose(odometry_path, pose); !s.ok()) return Fail(s.message());
    }
  }

  if (!o.truth) scenario.truth_poses.clear();
  // Ground-truth visibility from the dense scan set, one mask per worker.
  const CellBox box =
      GridGeometry(params.resolution, params.tile_size)
          .BoxCovering(scenario.xmin, scenario.ymin, scenario.xmax - 1e-9, scenario.ymax - 1e-9);
  std::vector<sim::VisibilityMask> masks(o.threads, sim::VisibilityMask(params, box));
  {
    io::ProgressBar progress("ground-truth scans", scenario.truth_poses.size(), "scans");
    ParallelFor(scenario.truth_poses.size(), o.threads, progress, [&](size_t k, int t) {
      sim::RayCastOptions rc;
      rc.seed = static_cast<unsigned>(1'000'000 + k);
      const auto pts =
          sim::SimulateScan(*scenario.world, scenario.beams, scenario.truth_poses[k], rc);
      if (Status s = masks[t].AddScan(pts, scenario.truth_poses[k]); !s.ok()) {
        std::lock_guard lock(error_mu);
        error = s.message();
      }
    });
  }
  if (!error.empty()) return Fail(error);
  for (int t = 1; t < o.threads; ++t) masks[0].Merge(masks[t]);
  if (o.truth) {
    const Raster truth = sim::MakeGroundTruth(*scenario.world, params, masks[0]);
    const std::string truth_path = (fs::path(o.out) / "ground_truth.tif").string();
    if (Status s = io::WriteGeoTiff(truth, truth_path); !s.ok()) return Fail(s.message());
  }

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  using Json = nlohmann::ordered_json;  // keys in the order scenario.json always had
  Json scenario_json;
  scenario_json["world"] = scenario.name;
  scenario_json["sensor"] = scenario.beams.name;
  scenario_json["mapping_scans"] = n;
  scenario_json["truth_scans"] = scenario.truth_poses.size();
  scenario_json["area_m"] = {JsonNumber<Json>(scenario.xmin), JsonNumber<Json>(scenario.ymin),
                             JsonNumber<Json>(scenario.xmax), JsonNumber<Json>(scenario.ymax)};
  scenario_json["resolution"] = JsonNumber<Json>(params.resolution);
  scenario_json["truth_visible_cells"] = masks[0].count();
  scenario_json["area_cells"] = box.cell_count();
  scenario_json["world_origin_in_source_crs"] = {JsonNumber<Json>(origin_x),
                                                 JsonNumber<Json>(origin_y)};
  scenario_json["seconds"] = JsonNumber<Json>(seconds);
  std::ofstream js(fs::path(o.out) / "scenario.json");
  js << JsonText(scenario_json);
  if (!js) return Fail("cannot write scenario.json in " + o.out);
  std::printf(
      "bgkmap simulate: %s, %zu %s scans, ground truth from %zu scans sees %lld of %lld cells%s, "
      "%.1f s -> %s\n",
      scenario.name.c_str(), n, scenario.beams.name.c_str(), scenario.truth_poses.size(),
      static_cast<long long>(masks[0].count()), static_cast<long long>(box.cell_count()),
      o.truth ? "" : " (--no-truth: not written)", seconds, o.out.c_str());
  return 0;
}

}  // namespace

void RegisterSimulateCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate the paper's City or Aerial lidar experiment with ground truth");
  cmd->add_option("world", o->world, "city | aerial")->required();
  cmd->add_option("--out", o->out, "Output directory (KITTI-like sequence + ground truth)")
      ->required();
  cmd->add_option("--config", o->config, "YAML map parameters used for the ground truth");
  cmd->add_option("--dem", o->dem, "aerial: ESRI ASCII grid of the terrain");
  cmd->add_option("--truth-spacing", o->truth_spacing,
                  "Metres between ground-truth scans (default: city 0.1, aerial 2.5)");
  cmd->add_option("--length", o->length, "city: metres of road (default 210)");
  cmd->add_option("--grid", o->grid, "aerial: n for n x n scan positions 10 m apart (default 13)");
  cmd->add_option("--threads", o->threads, "Worker threads for ray casting (default 2)");
  cmd->add_flag("!--no-truth", o->truth, "Only the mapping scans, no ground truth");
  cmd->add_option("--drift", o->drift,
                  "Also write odometry_poses.txt: the poses a drifting odometry reports, with "
                  "this position error per metre moved (e.g. 0.01; heading a fifth of it in rad/m)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->callback([o, &exit_code] { exit_code = RunSimulate(*o); });
}

}  // namespace bgkmap::cli
