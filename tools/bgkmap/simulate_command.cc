// `bgkmap simulate`: renders one of the paper's simulated experiments (city, aerial), or flat
// ground, into a KITTI-like sequence plus its ground truth (docs/results.md explains the worlds).
// With --change FILE (change_script.h) boxes appear and disappear at given scans, or drive
// through the scene (traffic): each scan sees the world as it is at that scan, and the ground
// truth is the world after the last change (the vehicles where they are at the last scan).
//   <out>/velodyne/NNNNNN.bin, <out>/poses.txt   the mapping scans, sensor frame
//   <out>/times.txt                              scan k at k / 10 s (10 Hz): the map time
//                                                forgetting ages by (half_life_s)
//   <out>/odometry_poses.txt                     with --drift: the same scans' poses as a
//                                                drifting odometry would report them
//   <out>/ground_truth.tif                       true elevation, traversability, state
//   <out>/scenario.json                          what was simulated (with --change: the
//                                                objects and their scans, for bgkmap eval)
//   <out>/traffic.json, ground_truth_static.tif  with moving objects: their footprint at every
//                                                scan, and the truth without them (eval's
//                                                stale trails and missed obstacles)
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/eval/change_score.h"
#include "bgkmap/io/esri_ascii_grid.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/progress_bar.h"
#include "bgkmap/sim/ground_truth.h"
#include "bgkmap/sim/odometry_drift.h"
#include "bgkmap/sim/ray_caster.h"
#include "bgkmap/sim/scenario.h"
#include "bgkmap/sim/scripted_objects.h"
#include "change_script.h"
#include "commands.h"
#include "json_output.h"

namespace bgkmap::cli {
namespace {

struct SimulateOptions {
  std::string world;
  std::string out;
  std::string config;
  std::string dem;
  double truth_spacing = 0;   // 0 = the scenario's default
  double length = 0;          // city: metres of road; flat: metres driven
  bool length_given = false;  // else city 210, flat 0
  int grid = 13;              // aerial only
  int scans = -1;             // flat only (default 20)
  std::string change;         // change script (change_script.h)
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

// changes.json: for each object that appears or disappears, the cells `bgkmap eval` judges its
// change on (eval/change_score.h), with their truth just before and just after it. An object is
// seen by the truth scans in the world that has it: the first scan's if it disappears, the last
// scan's if it appears. Compact JSON: one row [ix, iy, z_before, z_after, state_before,
// state_after] per cell.
Status WriteChanges(const sim::Scenario& scenario, const std::vector<sim::ScriptedObject>& objects,
                    const MapParams& params, const sim::VisibilityMask& visible_first,
                    const sim::VisibilityMask& visible_last, const std::string& path) {
  using Json = nlohmann::ordered_json;
  const GridGeometry geometry(params.resolution, params.tile_size);
  const double r = params.robot_radius;
  Json list = Json::array();
  for (const sim::ScriptedObject& obj : objects) {
    if (obj.Moves()) continue;  // traffic: traffic.json
    const bool removed = obj.disappear != sim::ScriptedObject::kNever;
    if (!removed && obj.appear == 0) continue;  // stands throughout
    const int scan = removed ? obj.disappear : obj.appear;
    const sim::Box b = obj.Placed(*scenario.world);
    // The cells whose centre lies within robot_radius of the footprint.
    sim::VisibilityMask region(
        params, geometry.BoxCovering(b.xmin - r, b.ymin - r, b.xmax + r, b.ymax + r));
    for (int iy = region.box().min.y; iy <= region.box().max.y; ++iy) {
      for (int ix = region.box().min.x; ix <= region.box().max.x; ++ix) {
        const double x = (ix + 0.5) * params.resolution, y = (iy + 0.5) * params.resolution;
        const double dx = std::max({b.xmin - x, 0.0, x - b.xmax});
        const double dy = std::max({b.ymin - y, 0.0, y - b.ymax});
        if (dx * dx + dy * dy <= r * r) region.Mark({ix, iy});
      }
    }
    const Raster before =
        sim::MakeGroundTruth(*sim::WorldAtScan(scenario.world, objects, scan - 1), params, region);
    const Raster after =
        sim::MakeGroundTruth(*sim::WorldAtScan(scenario.world, objects, scan), params, region);
    const sim::VisibilityMask& seen = removed ? visible_first : visible_last;
    const eval::ChangeKind kind =
        removed ? eval::ChangeKind::kRemoved : eval::ChangeKind::kAppeared;
    const std::vector<eval::ChangedCell> cells = eval::JudgedCells(
        before, after, kind, obj.height, [&](CellIndex c) { return seen.visible(c); });
    Json rows = Json::array();
    for (const eval::ChangedCell& c : cells) {
      rows.push_back({c.cell.x, c.cell.y, c.z_before, c.z_after, static_cast<int>(c.before),
                      static_cast<int>(c.after)});
    }
    Json j;
    j["name"] = obj.name;
    j["event"] = removed ? "removed" : "appeared";
    j["scan"] = scan;
    j["height"] = JsonNumber<Json>(obj.height);
    j["cells"] = std::move(rows);
    list.push_back(std::move(j));
  }
  Json root;
  root["resolution"] = JsonNumber<Json>(params.resolution);
  root["robot_radius"] = JsonNumber<Json>(params.robot_radius);
  root["objects"] = std::move(list);
  std::ofstream out(path);
  out << root.dump() << "\n";
  if (!out) return Status::IoError(path + ": cannot write");
  return Status::Ok();
}

// traffic.json: every moving object's footprint [xmin, ymin, xmax, ymax] at each scan it is
// present, from `first_scan` on; and ground_truth_static.tif, the truth of the last scan's world
// without them, over the cells the truth scans see and every cell within robot_radius of a
// vehicle's footprint at some scan (the cells eval judges trails and new obstacles on).
Status WriteTraffic(const sim::Scenario& scenario, const std::vector<sim::ScriptedObject>& objects,
                    const MapParams& params, const sim::VisibilityMask& visible,
                    const std::string& dir) {
  namespace fs = std::filesystem;
  using Json = nlohmann::ordered_json;
  const int n = static_cast<int>(scenario.mapping_poses.size());
  const GridGeometry geometry(params.resolution, params.tile_size);
  const double r = params.robot_radius;
  sim::VisibilityMask judged = visible;
  std::vector<sim::ScriptedObject> standing;
  Json vehicles = Json::array();
  for (const sim::ScriptedObject& obj : objects) {
    if (!obj.Moves()) {
      standing.push_back(obj);
      continue;
    }
    Json boxes = Json::array();
    const int first = obj.appear, last = std::min(n, obj.disappear);
    for (int k = first; k < last; ++k) {
      const sim::Box b = obj.Placed(*scenario.world, k);
      boxes.push_back({JsonNumber<Json>(b.xmin), JsonNumber<Json>(b.ymin), JsonNumber<Json>(b.xmax),
                       JsonNumber<Json>(b.ymax)});
      const CellBox near = geometry.BoxCovering(b.xmin - r, b.ymin - r, b.xmax + r, b.ymax + r);
      for (int iy = near.min.y; iy <= near.max.y; ++iy) {
        for (int ix = near.min.x; ix <= near.max.x; ++ix) judged.Mark({ix, iy});
      }
    }
    Json v;
    v["name"] = obj.name;
    v["first_scan"] = first;
    v["boxes"] = std::move(boxes);
    vehicles.push_back(std::move(v));
  }
  Json root;
  root["resolution"] = JsonNumber<Json>(params.resolution);
  root["robot_radius"] = JsonNumber<Json>(params.robot_radius);
  root["scans"] = n;
  root["vehicles"] = std::move(vehicles);
  const std::string path = (fs::path(dir) / "traffic.json").string();
  std::ofstream out(path);
  out << root.dump() << "\n";
  if (!out) return Status::IoError(path + ": cannot write");
  const Raster truth =
      sim::MakeGroundTruth(*sim::WorldAtScan(scenario.world, standing, n - 1), params, judged);
  return io::WriteGeoTiff(truth, (fs::path(dir) / "ground_truth_static.tif").string());
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
  if (o.scans >= 0 && o.world != "flat") return Usage("--scans is for the flat world only");
  if (o.world == "city") {
    const double length = o.length_given ? o.length : 210.0;
    if (!(length > 0)) return Usage("--length must be > 0");
    scenario = sim::MakeCityScenario(length, 1.0, o.truth_spacing > 0 ? o.truth_spacing : 0.1);
  } else if (o.world == "flat") {
    const int scans = o.scans < 0 ? 20 : o.scans;
    if (scans < 1) return Usage("--scans must be at least 1");
    if (!(o.length >= 0)) return Usage("--length must be >= 0");
    scenario = sim::MakeFlatScenario(scans, o.length, o.truth_spacing > 0 ? o.truth_spacing : 0.5);
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
    return Usage("unknown world '" + o.world + "' (expected city, aerial or flat)");
  }
  const size_t n = scenario.mapping_poses.size();
  std::vector<sim::ScriptedObject> objects;
  if (!o.change.empty()) {
    Result<std::vector<sim::ScriptedObject>> script =
        LoadChangeScript(o.change, static_cast<int>(n));
    if (!script.ok()) return Fail(script.status().message());
    objects = std::move(script).value();
  }
  // The ground truth's world: as it is after the last change (at the last scan).
  const std::shared_ptr<const sim::World> final_world =
      sim::WorldAtScan(scenario.world, objects, static_cast<int>(n) - 1);

  std::error_code ec;
  fs::create_directories(fs::path(o.out) / "velodyne", ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());
  const std::string poses_path = (fs::path(o.out) / "poses.txt").string();
  fs::remove(poses_path, ec);

  // Mapping scans: one file each, poses appended in order afterwards.
  std::mutex error_mu;
  std::string error;
  {
    io::ProgressBar progress("simulating " + scenario.name, n, "scans");
    ParallelFor(n, o.threads, progress, [&](size_t k, int) {
      sim::RayCastOptions rc;
      rc.seed = static_cast<unsigned>(k + 1);
      const std::shared_ptr<const sim::World> world =
          sim::WorldAtScan(scenario.world, objects, static_cast<int>(k));
      const auto pts = sim::SimulateScan(*world, scenario.beams, scenario.mapping_poses[k], rc);
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
  {
    const std::string times_path = (fs::path(o.out) / "times.txt").string();
    std::ofstream times(times_path, std::ios::trunc);
    for (size_t k = 0; k < n; ++k) times << static_cast<double>(k) * sim::kScanPeriodS << '\n';
    if (!times.good()) return Fail(times_path + ": cannot write");
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
  // Ground-truth visibility of a world from the dense scan set, one mask per worker.
  const CellBox box =
      GridGeometry(params.resolution, params.tile_size)
          .CellsOfRegion(scenario.xmin, scenario.ymin, scenario.xmax, scenario.ymax);
  auto visibility = [&](const sim::World& world, const std::string& label) {
    std::vector<sim::VisibilityMask> masks(o.threads, sim::VisibilityMask(params, box));
    io::ProgressBar progress(label, scenario.truth_poses.size(), "scans");
    ParallelFor(scenario.truth_poses.size(), o.threads, progress, [&](size_t k, int t) {
      sim::RayCastOptions rc;
      rc.seed = static_cast<unsigned>(1'000'000 + k);
      const auto pts = sim::SimulateScan(world, scenario.beams, scenario.truth_poses[k], rc);
      if (Status s = masks[t].AddScan(pts, scenario.truth_poses[k]); !s.ok()) {
        std::lock_guard lock(error_mu);
        error = s.message();
      }
    });
    for (int t = 1; t < o.threads; ++t) masks[0].Merge(masks[t]);
    return std::move(masks[0]);
  };
  const sim::VisibilityMask visible = visibility(*final_world, "ground-truth scans");
  if (!error.empty()) return Fail(error);
  if (o.truth) {
    const Raster truth = sim::MakeGroundTruth(*final_world, params, visible);
    const std::string truth_path = (fs::path(o.out) / "ground_truth.tif").string();
    if (Status s = io::WriteGeoTiff(truth, truth_path); !s.ok()) return Fail(s.message());
  }
  bool has_events = false, has_traffic = false;
  for (const sim::ScriptedObject& obj : objects) {
    has_events |= !obj.Moves() && (obj.appear > 0 || obj.disappear != sim::ScriptedObject::kNever);
    has_traffic |= obj.Moves();
  }
  if (o.truth && has_traffic) {
    if (Status s = WriteTraffic(scenario, objects, params, visible, o.out); !s.ok())
      return Fail(s.message());
  }
  if (o.truth && has_events) {
    // The world of the first scan, and the cells each change is judged on (eval/change_score.h).
    const std::shared_ptr<const sim::World> first_world =
        sim::WorldAtScan(scenario.world, objects, 0);
    const sim::VisibilityMask visible_first =
        visibility(*first_world, "ground-truth scans, world of scan 0");
    if (!error.empty()) return Fail(error);
    const Raster before = sim::MakeGroundTruth(*first_world, params, visible_first);
    const std::string before_path = (fs::path(o.out) / "ground_truth_before.tif").string();
    if (Status s = io::WriteGeoTiff(before, before_path); !s.ok()) return Fail(s.message());
    if (Status s = WriteChanges(scenario, objects, params, visible_first, visible,
                                (fs::path(o.out) / "changes.json").string());
        !s.ok()) {
      return Fail(s.message());
    }
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
  scenario_json["truth_visible_cells"] = visible.count();
  scenario_json["area_cells"] = box.cell_count();
  scenario_json["world_origin_in_source_crs"] = {JsonNumber<Json>(origin_x),
                                                 JsonNumber<Json>(origin_y)};
  if (!o.change.empty()) {
    // What `bgkmap eval` needs to score the change: each object's footprint, height and scans.
    Json list = Json::array();
    for (const sim::ScriptedObject& obj : objects) {
      const sim::Box b = obj.Placed(*scenario.world, obj.appear);  // where it starts
      Json j;
      j["name"] = obj.name;
      j["center"] = {JsonNumber<Json>(obj.center_x), JsonNumber<Json>(obj.center_y)};
      if (obj.Moves())
        j["velocity"] = {JsonNumber<Json>(obj.velocity_x), JsonNumber<Json>(obj.velocity_y)};
      j["size"] = {JsonNumber<Json>(obj.size_x), JsonNumber<Json>(obj.size_y)};
      j["height"] = JsonNumber<Json>(obj.height);
      j["top_z"] = JsonNumber<Json>(b.height);
      j["box_m"] = {JsonNumber<Json>(b.xmin), JsonNumber<Json>(b.ymin), JsonNumber<Json>(b.xmax),
                    JsonNumber<Json>(b.ymax)};
      j["appear"] = obj.appear > 0 ? Json(obj.appear) : Json(nullptr);
      j["disappear"] =
          obj.disappear != sim::ScriptedObject::kNever ? Json(obj.disappear) : Json(nullptr);
      list.push_back(std::move(j));
    }
    scenario_json["change_script"] = o.change;
    scenario_json["objects"] = std::move(list);
    scenario_json["truth_world_scan"] = n - 1;  // the ground truth is the world of the last scan
  }
  scenario_json["seconds"] = JsonNumber<Json>(seconds);
  std::ofstream js(fs::path(o.out) / "scenario.json");
  js << JsonText(scenario_json);
  if (!js) return Fail("cannot write scenario.json in " + o.out);
  std::string scripted;
  if (!objects.empty()) {
    scripted += ", ";
    scripted += std::to_string(objects.size());
    scripted += " scripted objects";
  }
  std::printf(
      "bgkmap simulate: %s, %zu %s scans%s, ground truth from %zu scans sees %lld of %lld "
      "cells%s, %.1f s -> %s\n",
      scenario.name.c_str(), n, scenario.beams.name.c_str(), scripted.c_str(),
      scenario.truth_poses.size(), static_cast<long long>(visible.count()),
      static_cast<long long>(box.cell_count()), o.truth ? "" : " (--no-truth: not written)",
      seconds, o.out.c_str());
  return 0;
}

}  // namespace

void RegisterSimulateCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulate the paper's City or Aerial lidar experiment, or flat ground, with ground truth");
  cmd->add_option("world", o->world, "city | aerial | flat")->required();
  cmd->add_option("--out", o->out, "Output directory (KITTI-like sequence + ground truth)")
      ->required();
  cmd->add_option("--config", o->config, "YAML map parameters used for the ground truth");
  cmd->add_option("--dem", o->dem, "aerial: ESRI ASCII grid of the terrain");
  cmd->add_option("--truth-spacing", o->truth_spacing,
                  "Metres between ground-truth scans (default: city 0.1, aerial 2.5, flat 0.5)");
  CLI::Option* length = cmd->add_option(
      "--length", o->length,
      "city: metres of road driven, the street as long (default 210); flat: metres driven "
      "along +x (default 0: standing still)");
  cmd->add_option("--scans", o->scans, "flat: number of scans (default 20)");
  cmd->add_option("--change", o->change,
                  "YAML/JSON script of boxes that appear or disappear at given scans "
                  "(docs/results.md, \"Changing worlds\")");
  cmd->add_option("--grid", o->grid, "aerial: n for n x n scan positions 10 m apart (default 13)");
  cmd->add_option("--threads", o->threads, "Worker threads for ray casting (default 2)");
  cmd->add_flag("!--no-truth", o->truth, "Only the mapping scans, no ground truth");
  cmd->add_option("--drift", o->drift,
                  "Also write odometry_poses.txt: the poses a drifting odometry reports, with "
                  "this position error per metre moved (e.g. 0.01; heading a fifth of it in rad/m)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->callback([o, length, &exit_code] {
    o->length_given = length->count() > 0;
    exit_code = RunSimulate(*o);
  });
}

}  // namespace bgkmap::cli
