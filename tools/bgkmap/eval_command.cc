// `bgkmap eval`: maps a sequence with each method and scores it against the ground truth
// (coverage, elevation MSE, ROC/AUC, stage times, scans skipped at the scan rate). With a
// changes.json (`bgkmap simulate --change`), also the stale-obstacle and missed-new-obstacle
// rates per scan after each change (eval/change_score.h). With the robot's footprint, also the
// truth that needs no survey, on real drives too (eval/drive_score.h): the driven cells'
// known, traversable and blocked shares (and why), and the odd scans' map against the even's.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/core/vertical_alignment.h"
#include "bgkmap/eval/change_score.h"
#include "bgkmap/eval/drive_score.h"
#include "bgkmap/eval/map_score.h"
#include "bgkmap/eval/realtime_gate.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/progress_bar.h"
#include "bgkmap/sim/pose_noise.h"
#include "commands.h"
#include "drive_eval.h"
#include "eval_report.h"
#include "json_output.h"
#include "scan_source.h"

namespace bgkmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

struct EvalOptions {
  std::string sequence;
  std::string truth;
  std::string config;
  std::string out;
  std::string name = "dataset";
  std::vector<std::string> methods = {"baseline", "bgk-trav",     "bgk+",
                                      "one-step", "bgk-obstacle", "bgk-ll"};
  double rate_hz = 10.0;
  bool figures = true;
  std::string changes;    // changes.json; default <sequence>/changes.json if it exists
  int change_scans = 10;  // scans after each change to score
  // The robot's footprint (drive scores): a disc radius, or a box (length, width) with the
  // sensor's offset from its centre.
  double footprint_radius = 0;
  std::vector<double> footprint_box;
  std::vector<double> sensor_offset;
  std::string poses;     // map with these poses instead of the sequence's (driven cells: its own)
  bool odd_even = true;  // with a footprint: also the odd scans' map against the even scans'
  std::string traffic;   // traffic.json; default <sequence>/traffic.json if it exists
  int trail_scans = 5;   // a trail is judged this many scans after the vehicle left a cell
  int new_scans = 1;     // a new obstacle this many scans after it arrived
  std::vector<int> figure_scans;  // with a footprint: also the drive figure after these scans
  std::string trace;      // with a footprint: every driven cell's statistics after every scan (CSV)
  double pose_noise = 0;  // > 0: the mapping poses perturbed (sim/pose_noise.h) at this scale
  uint32_t pose_noise_seed = 1;
  std::vector<std::string> pose_noise_parts;  // keep only these components (default: all)
  // Align each scan's z to the map built so far before integrating it, as a robot's
  // localization would (core/vertical_alignment.h): a robot-side step, off by default.
  bool align_z = false;
  VerticalAlignmentOptions align;
};

// The pose error of --pose-noise with only the components named kept (xy, z, tilt, yaw, drift).
Result<sim::PoseNoiseOptions> PoseNoiseOf(const EvalOptions& o) {
  sim::PoseNoiseOptions n = sim::PoseNoiseOptions().Scaled(o.pose_noise);
  n.seed = o.pose_noise_seed;
  if (o.pose_noise_parts.empty()) return n;
  const sim::PoseNoiseOptions all = n;
  n.xy_m = n.z_m = n.roll_pitch_deg = n.yaw_deg = n.drift_z_m = n.drift_roll_pitch_deg = 0;
  for (const std::string& part : o.pose_noise_parts) {
    if (part == "xy") {
      n.xy_m = all.xy_m;
    } else if (part == "z") {
      n.z_m = all.z_m;
    } else if (part == "tilt") {
      n.roll_pitch_deg = all.roll_pitch_deg;
    } else if (part == "yaw") {
      n.yaw_deg = all.yaw_deg;
    } else if (part == "drift") {
      n.drift_z_m = all.drift_z_m;
      n.drift_roll_pitch_deg = all.drift_roll_pitch_deg;
    } else {
      return Status::InvalidArgument("--pose-noise-parts: unknown part '" + part +
                                     "' (xy, z, tilt, yaw, drift)");
    }
  }
  return n;
}

// One object's change from changes.json.
struct Change {
  eval::ChangeKind kind;
  int scan;  // the first scan of the changed world
  std::vector<eval::ChangedCell> cells;
};

Result<std::vector<Change>> LoadChanges(const std::string& path, const MapParams& params) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot read");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
    const double res = j.at("resolution").get<double>();
    const double radius = j.at("robot_radius").get<double>();
    if (std::abs(res - params.resolution) > 1e-9 || std::abs(radius - params.robot_radius) > 1e-9) {
      std::ostringstream m;
      m << path << ": made with resolution " << res << " m and robot_radius " << radius
        << " m, the map uses " << params.resolution << " m and " << params.robot_radius
        << " m (pass the simulation's --config)";
      return Status::InvalidArgument(m.str());
    }
    std::vector<Change> changes;
    for (const auto& o : j.at("objects")) {
      Change c;
      const std::string event = o.at("event").get<std::string>();
      if (event != "removed" && event != "appeared") {
        return Status::InvalidArgument(path + ": unknown event '" + event + "'");
      }
      c.kind = event == "removed" ? eval::ChangeKind::kRemoved : eval::ChangeKind::kAppeared;
      c.scan = o.at("scan").get<int>();
      for (const auto& row : o.at("cells")) {
        eval::ChangedCell cell;
        cell.cell = {row.at(0).get<int>(), row.at(1).get<int>()};
        cell.z_before = row.at(2).get<float>();
        cell.z_after = row.at(3).get<float>();
        cell.before = static_cast<CellState>(row.at(4).get<int>());
        cell.after = static_cast<CellState>(row.at(5).get<int>());
        cell.moved = std::abs(static_cast<double>(cell.z_before) - cell.z_after) >
                     0.5 * o.at("height").get<double>();
        c.cells.push_back(cell);
      }
      changes.push_back(std::move(c));
    }
    return changes;
  } catch (const nlohmann::json::exception& e) {
    return Status::InvalidArgument(path + ": " + e.what());
  }
}

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap eval: %s\n", msg.c_str());
  return kExitFailure;
}

// A bad command line: the same line, exit code kExitUsage.
int Usage(const std::string& msg) {
  Fail(msg);
  return kExitUsage;
}

struct Run {
  std::unique_ptr<TerrainMap> map;
  std::vector<eval::ScanTiming> timings;
  StageTimes sum;
  double prepare = 0, max_scan = 0;
  AlignmentStats alignment;
};

// The pose scan k is integrated with: its own, or with `align` its z aligned to the map as it
// stands (the robot's step, core/vertical_alignment.h; timed apart from the map's stages).
Result<Pose> PoseToIntegrate(const MapParams& params, const SourceScan& scan, const TerrainMap& map,
                             const VerticalAlignmentOptions* align, AlignmentStats* stats) {
  if (align == nullptr || scan.frame_is_map) return scan.pose;
  const auto t0 = Clock::now();
  Result<PreparedScan> prepared = PrepareScan(params, scan.points, scan.pose);
  if (!prepared.ok()) return prepared.status();
  const VerticalAlignment a = AlignScanVertically(params, *prepared, MapHeightsOf(map), *align);
  stats->seconds += std::chrono::duration<double>(Clock::now() - t0).count();
  switch (a.outcome) {
    case AlignmentOutcome::kAligned:
      ++stats->aligned;
      stats->sum_abs_dz += std::abs(a.dz);
      stats->max_abs_dz = std::max(stats->max_abs_dz, std::abs(a.dz));
      if (a.Levelled()) {
        ++stats->levelled;
        stats->sum_tilt_deg += a.TiltDegrees();
        stats->max_tilt_deg = std::max(stats->max_tilt_deg, a.TiltDegrees());
      }
      break;
    case AlignmentOutcome::kBeyondBound:
      ++stats->beyond_bound;
      break;
    default:
      ++stats->too_few_cells;
  }
  return AlignedPose(scan.pose, a);
}

// Integrates the scans with admitted[k] (all if empty), timing each one; after_scan(k, map), if
// given, looks at the map after scan k (outside the timings). With `align`, each scan's z is
// first aligned to the map as it stands.
Result<Run> MapScans(const MapParams& params, const std::vector<SourceScan>& scans,
                     const std::vector<bool>& admitted, const std::string& label,
                     const VerticalAlignmentOptions* align,
                     const std::function<void(size_t, const TerrainMap&)>& after_scan = {}) {
  Result<std::unique_ptr<TerrainMap>> created = TerrainMap::Create(params);
  if (!created.ok()) return created.status();
  Run run;
  run.map = std::move(created).value();
  io::ProgressBar progress(label, scans.size(), "scans");
  for (size_t k = 0; k < scans.size(); ++k) {
    progress.Add();
    if (!admitted.empty() && !admitted[k]) continue;
    Result<Pose> pose = PoseToIntegrate(params, scans[k], *run.map, align, &run.alignment);
    if (!pose.ok()) return pose.status();
    const auto t0 = Clock::now();
    // The scans' times are the map's clock, as in `bgkmap build` (forgetting, transient
    // objects); LoadInputs gave a sequence without times its nominal rate's.
    const int64_t stamp = MapTimeNs(scans[k].time_s, scans.front().time_s);
    Result<ScanReport> r =
        run.map->IntegrateScan(scans[k].points, *pose, scans[k].frame_is_map, stamp);
    const double total = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!r.ok()) return Status(r.status());
    const StageTimes& t = r->times;
    const double p2 = t.features + t.traversability;
    run.timings.push_back({total - p2, p2});
    run.sum.elevation += t.elevation;
    run.sum.features += t.features;
    run.sum.traversability += t.traversability;
    run.prepare += total - t.elevation - p2;
    run.max_scan = std::max(run.max_scan, total);
    if (after_scan) after_scan(k, *run.map);
  }
  return run;
}

// The scans with odd (or even) index.
std::vector<bool> EveryOther(size_t n, size_t parity) {
  std::vector<bool> admitted(n);
  for (size_t k = 0; k < n; ++k) admitted[k] = k % 2 == parity;
  return admitted;
}

Raster FigureLayers(const TerrainMap& map, const Raster& truth) {
  return ExtractRaster(map, truth.box, {Layer::kState, Layer::kTraversabilityVariance});
}

// What every method is run on, read before any mapping.
struct EvalInputs {
  MapParams params;
  std::vector<Method> methods;
  std::optional<Raster> truth;
  std::vector<SourceScan> scans;  // with the poses the maps are built with
  std::vector<Change> changes;
  DriveInputs drive;
};

// Line k of a KITTI poses.txt for each of n scans.
Result<std::vector<Pose>> ReadPoseFile(const std::string& path, size_t n) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot read");
  std::vector<Pose> poses;
  std::string line;
  for (size_t k = 0; k < n && std::getline(in, line); ++k) {
    Result<Pose> pose = io::ParseKittiPoseLine(line);
    if (!pose.ok()) {
      return Status::InvalidArgument(path + ":" + std::to_string(k + 1) + ": " +
                                     pose.status().message());
    }
    poses.push_back(*pose);
  }
  if (poses.size() < n) {
    return Status::InvalidArgument(path + ": " + std::to_string(poses.size()) + " poses for " +
                                   std::to_string(n) + " scans");
  }
  return poses;
}

// The footprint the options describe, if any; a usage error names the option.
Result<std::optional<eval::Footprint>> FootprintOf(const EvalOptions& o) {
  const bool disc = o.footprint_radius != 0, box = !o.footprint_box.empty();
  if (disc && box) return Status::InvalidArgument("give --footprint-radius or --footprint-box");
  if (!o.sensor_offset.empty() && !box)
    return Status::InvalidArgument("--sensor-offset needs --footprint-box");
  if (disc) {
    if (!(o.footprint_radius > 0)) return Status::InvalidArgument("--footprint-radius must be > 0");
    return std::optional(eval::Footprint::Disc(o.footprint_radius));
  }
  if (!box) return std::optional<eval::Footprint>();
  if (o.footprint_box.size() != 2 || !(o.footprint_box[0] > 0) || !(o.footprint_box[1] > 0))
    return Status::InvalidArgument("--footprint-box needs LENGTH,WIDTH, both > 0");
  if (!o.sensor_offset.empty() && o.sensor_offset.size() != 2)
    return Status::InvalidArgument("--sensor-offset needs X,Y");
  const double sx = o.sensor_offset.empty() ? 0 : o.sensor_offset[0];
  const double sy = o.sensor_offset.empty() ? 0 : o.sensor_offset[1];
  return std::optional(eval::Footprint::Box(o.footprint_box[0], o.footprint_box[1], sx, sy));
}

// Reads the parameters, truth, scans, changes and driven cells; 0, or the exit code after the
// message.
// The poses the maps are built with (--poses, --pose-noise), the driven cells along the
// sequence's own poses and the traffic; 0, or the exit code after the message.
int LoadDrive(const EvalOptions& o, const sim::PoseNoiseOptions& noise, EvalInputs* in) {
  namespace fs = std::filesystem;
  const MapParams& params = in->params;
  DriveInputs& drive = in->drive;
  std::vector<Pose>& path = drive.path;
  for (const SourceScan& s : in->scans) path.push_back(s.pose);
  if (!o.poses.empty()) {
    Result<std::vector<Pose>> poses = ReadPoseFile(o.poses, in->scans.size());
    if (!poses.ok()) return Fail(poses.status().message());
    for (size_t k = 0; k < in->scans.size(); ++k) in->scans[k].pose = (*poses)[k];
  }
  if (o.pose_noise > 0) {
    std::vector<Pose> mapping;
    for (const SourceScan& s : in->scans) mapping.push_back(s.pose);
    mapping = sim::PerturbPoses(mapping, noise);
    for (size_t k = 0; k < in->scans.size(); ++k) in->scans[k].pose = mapping[k];
  }
  if (drive.footprint) {
    drive.driven = eval::DrivenCells(GridGeometry(params.resolution, params.tile_size), path,
                                     *drive.footprint, params.sensor_height);
    drive.arrivals.resize(in->scans.size());
    for (const eval::DrivenCell& d : drive.driven) drive.arrivals[d.first_scan].push_back(d);
  }
  std::error_code ec;
  const std::string traffic_path =
      !o.traffic.empty() ? o.traffic : (fs::path(o.sequence) / "traffic.json").string();
  if (!o.traffic.empty() || fs::exists(traffic_path, ec)) {
    if (Status s = LoadTraffic(traffic_path, params, &drive); !s.ok()) return Fail(s.message());
    for (size_t k = 0; k < in->scans.size(); ++k) {
      Result<PreparedScan> prepared = PrepareScan(params, in->scans[k].points, path[k]);
      if (!prepared.ok()) return Fail(prepared.status().message());
      std::vector<CellIndex> cells;
      for (const ObservedCell& c : prepared->cells) cells.push_back(c.cell);
      drive.observed.push_back(std::move(cells));  // sorted, as PrepareScan sorts them
    }
  }
  return 0;
}

// Reads the parameters, truth, scans, changes and the drive's inputs; 0, or the exit code after
// the message.
int LoadInputs(const EvalOptions& o, EvalInputs* in) {
  namespace fs = std::filesystem;
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  in->params = *loaded;
  const MapParams& params = in->params;
  if (!(o.rate_hz > 0)) return Usage("--rate must be > 0");
  if (o.change_scans < 1) return Usage("--change-scans must be at least 1");
  if (o.trail_scans < 1 || o.new_scans < 1)
    return Usage("--trail-scans and --new-obstacle-scans must be at least 1");
  if (!(o.pose_noise >= 0)) return Usage("--pose-noise must be >= 0");
  if (!(o.align.radius_m > 0)) return Usage("--align-z-radius must be > 0");
  if (!(o.align.max_tilt_deg >= 0 && o.align.max_tilt_deg <= 10))
    return Usage("--align-tilt must be between 0 and 10 degrees");
  if (o.align.max_tilt_deg > 0 && !o.align_z)
    return Usage("--align-tilt levels what --align-z compares: give both");
  Result<sim::PoseNoiseOptions> noise = PoseNoiseOf(o);
  if (!noise.ok()) return Usage(noise.status().message());
  for (const std::string& name : o.methods) {
    Result<Method> m = ParseMethod(name);
    if (!m.ok()) return Usage(m.status().message());
    in->methods.push_back(*m);
  }
  Result<std::optional<eval::Footprint>> footprint = FootprintOf(o);
  if (!footprint.ok()) return Usage(footprint.status().message());
  in->drive.footprint = *footprint;
  std::error_code ec;
  const std::string truth_path =
      !o.truth.empty() ? o.truth : (fs::path(o.sequence) / "ground_truth.tif").string();
  if (!o.truth.empty() || fs::exists(truth_path, ec)) {
    Result<Raster> truth = io::ReadGeoTiff(truth_path);
    if (!truth.ok()) return Fail(truth.status().message());
    if (truth->Find(Layer::kState) == nullptr || truth->Find(Layer::kElevation) == nullptr) {
      return Fail(truth_path + ": ground truth needs elevation and state bands");
    }
    if (truth->stride != 1 || std::abs(truth->resolution - params.resolution) > 1e-9) {
      return Fail(truth_path + ": ground truth resolution " + std::to_string(truth->resolution) +
                  " m differs from the map resolution " + std::to_string(params.resolution) + " m");
    }
    in->truth = std::move(truth).value();
  } else if (!in->drive.footprint) {
    return Usage(truth_path +
                 " does not exist: give --truth, or the robot's footprint "
                 "(--footprint-radius or --footprint-box) to score the driven cells");
  }
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.sequence);
  if (!source.ok()) return Fail(source.status().message());
  for (size_t k = 0; k < (*source)->size(); ++k) {  // read up front: no file I/O in the timings
    Result<SourceScan> s = (*source)->Read(k);
    if (!s.ok()) return Fail(s.status().message());
    s->time_s = ScanTimeS(*s, k, o.rate_hz);  // without times.txt: --rate apart
    in->scans.push_back(std::move(s).value());
  }
  if (int code = LoadDrive(o, *noise, in); code != 0) return code;
  const std::string changes_path =
      !o.changes.empty() ? o.changes : (fs::path(o.sequence) / "changes.json").string();
  if (in->truth && (!o.changes.empty() || fs::exists(changes_path, ec))) {
    Result<std::vector<Change>> changes = LoadChanges(changes_path, params);
    if (!changes.ok()) return Fail(changes.status().message());
    in->changes = std::move(changes).value();
  }
  return 0;
}

// The map of the odd scans against the map of the even scans, over every cell and over the
// driven cells.
Status ScoreOddEven(const MapParams& p, const std::vector<SourceScan>& scans,
                    const std::vector<eval::DrivenCell>& driven, const std::string& name,
                    const VerticalAlignmentOptions* align, MethodResult* m) {
  Result<Run> odd = MapScans(p, scans, EveryOther(scans.size(), 1), name + " (odd scans)", align);
  if (!odd.ok()) return odd.status();
  Result<Run> even = MapScans(p, scans, EveryOther(scans.size(), 0), name + " (even scans)", align);
  if (!even.ok()) return even.status();
  std::vector<CellIndex> cells;
  for (const eval::DrivenCell& d : driven) cells.push_back(d.cell);
  m->odd_even = eval::CompareMaps(*odd->map, *even->map);
  m->odd_even_driven = eval::CompareMaps(*odd->map, *even->map, cells);
  return Status::Ok();
}

// One method: the offline map (and its change, drive and traffic scores), the odd and even maps,
// and with a truth the real-time replay.
Result<MethodResult> EvaluateMethod(const EvalOptions& o, const EvalInputs& in, Method method) {
  MapParams p = in.params;
  p.method = method;
  const std::string name(MethodName(method));
  MethodResult m;
  // The changes, scored on the map after each scan from just before a change (j = 0) to
  // --change-scans after it.
  const size_t points = static_cast<size_t>(o.change_scans) + 1;
  if (!in.changes.empty()) {
    m.removed.resize(points);
    m.appeared.resize(points);
  }
  const DriveOutputs outputs{o.out, o.figures, o.figure_scans, o.trace, o.trail_scans, o.new_scans};
  DriveObserver drive(p, name, in.drive, in.scans, outputs);
  auto after_scan = [&](size_t k, const TerrainMap& map) {
    drive.AfterScan(k, map);
    for (const Change& c : in.changes) {
      const long j = static_cast<long>(k) + 1 - c.scan;  // scans of the changed world mapped
      if (j < 0 || j >= static_cast<long>(points)) continue;
      (c.kind == eval::ChangeKind::kRemoved ? m.removed : m.appeared)[static_cast<size_t>(j)] +=
          eval::ScoreChange(map, c.cells, c.kind);
    }
  };
  const std::vector<SourceScan>& scans = in.scans;
  const VerticalAlignmentOptions* align = o.align_z ? &o.align : nullptr;
  Result<Run> offline = MapScans(p, scans, {}, name + " (all scans)", align, after_scan);
  if (!offline.ok()) return offline.status();
  m.method = method;
  m.scans = scans.size();
  const double n = static_cast<double>(scans.size());
  m.prepare_s = offline->prepare / n;
  m.elevation_s = offline->sum.elevation / n;
  m.features_s = offline->sum.features / n;
  m.traversability_s = offline->sum.traversability / n;
  m.max_scan_s = offline->max_scan;
  m.alignment = offline->alignment;
  if (Status s = drive.Finish(*offline->map, &m); !s.ok()) return s;
  if (in.drive.footprint && o.odd_even) {
    if (Status s = ScoreOddEven(p, scans, in.drive.driven, name, align, &m); !s.ok()) return s;
  }
  if (!in.truth) return m;
  m.offline = eval::ScoreMap(*offline->map, *in.truth);
  // Real time: replay the measured timings through the two-process gate, then map only the
  // scans it admits (their own timings differ slightly: the map they meet is sparser).
  const std::vector<bool> admitted = eval::AdmitScans(offline->timings, 1.0 / o.rate_hz);
  for (bool a : admitted) m.skipped += a ? 0 : 1;
  if (m.skipped == 0) {
    m.realtime = m.offline;
    m.maps = FigureLayers(*offline->map, *in.truth);
  } else {
    Result<Run> realtime = MapScans(p, scans, admitted, name + " (real time)", align);
    if (!realtime.ok()) return realtime.status();
    m.realtime = eval::ScoreMap(*realtime->map, *in.truth);
    m.maps = FigureLayers(*realtime->map, *in.truth);
  }
  return m;
}

int RunEval(const EvalOptions& o) {
  namespace fs = std::filesystem;
  const auto start = Clock::now();
  EvalInputs in;
  if (int code = LoadInputs(o, &in); code != 0) return code;
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());

  EvalReport report;
  report.name = o.name;
  report.sequence = o.sequence;
  report.rate_hz = o.rate_hz;
  report.params = in.params;
  report.has_truth = in.truth.has_value();
  report.has_changes = !in.changes.empty();
  report.has_drive = in.drive.footprint.has_value();
  report.has_traffic = in.drive.static_truth.has_value();
  for (const eval::VehicleTrack& v : in.drive.vehicles) report.vehicle_names.push_back(v.name);
  report.trail_scans = o.trail_scans;
  report.new_scans = o.new_scans;
  report.has_odd_even = report.has_drive && o.odd_even;
  if (in.drive.footprint) report.footprint = in.drive.footprint->Describe();
  report.poses = o.poses;
  report.pose_noise = o.pose_noise;
  report.pose_noise_seed = o.pose_noise_seed;
  report.align_z = o.align_z;
  report.align_radius_m = o.align.radius_m;
  for (Method method : in.methods) {
    Result<MethodResult> m = EvaluateMethod(o, in, method);
    if (!m.ok()) return Fail(std::string(MethodName(method)) + ": " + m.status().message());
    report.methods.push_back(std::move(m).value());
  }

  auto write = [&](const std::string& file, const std::string& text) {
    std::ofstream f(fs::path(o.out) / file);
    f << text;
    return static_cast<bool>(f);
  };
  if (!write("eval.json", ToJson(report))) return Fail(o.out + "/eval.json: cannot write");
  const std::string table = ToMarkdown(report);
  if (!write("table.md", table)) return Fail(o.out + "/table.md: cannot write");
  if (o.figures && in.truth) {
    std::string note;
    if (Status s = WriteFigures(report, *in.truth, o.out, &note); !s.ok()) return Fail(s.message());
    if (!note.empty()) std::fprintf(stderr, "bgkmap eval: %s\n", note.c_str());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("%s\nbgkmap eval: %s, %zu scans, %zu methods, %.1f s -> %s\n", table.c_str(),
              o.name.c_str(), in.scans.size(), in.methods.size(), seconds, o.out.c_str());
  return 0;
}

}  // namespace

void RegisterEvalCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval",
      "Score the mapping methods on a sequence: against its ground truth (simulated), and with "
      "the robot's footprint on the cells it drove over (also real drives)");
  cmd->add_option("sequence", o->sequence,
                  "KITTI-like directory (bgkmap simulate, or a real drive)")
      ->required();
  cmd->add_option("--truth", o->truth,
                  "Ground-truth GeoTIFF (default: <sequence>/ground_truth.tif, if present)");
  cmd->add_option("--config", o->config, "YAML map parameters (the ground truth's)");
  cmd->add_option("--out", o->out, "Output directory for eval.json, table.md and figures")
      ->required();
  cmd->add_option("--name", o->name, "Dataset name in tables and figures");
  cmd->add_option("--methods", o->methods, "Methods to compare (default: all six)")->delimiter(',');
  cmd->add_option("--rate", o->rate_hz,
                  "Scan rate, Hz (default 10): of the real-time replay, and the scans' spacing in "
                  "map time for a sequence without times.txt");
  cmd->add_flag("!--no-figures", o->figures, "Skip the gnuplot figures");
  cmd->add_option("--changes", o->changes,
                  "changes.json of bgkmap simulate --change (default: <sequence>/changes.json if "
                  "present): also score stale and missed obstacles per scan after each change");
  cmd->add_option("--change-scans", o->change_scans,
                  "Scans after each change to score (default 10)");
  cmd->add_option("--footprint-radius", o->footprint_radius,
                  "The robot's footprint, a disc of this radius (m) around the sensor: score the "
                  "driven cells (docs/results.md, \"Real drives\"); no ground truth needed");
  cmd->add_option("--footprint-box", o->footprint_box,
                  "The robot's footprint, a box LENGTH,WIDTH (m) along the sensor's heading")
      ->delimiter(',')
      ->expected(2);
  cmd->add_option("--sensor-offset", o->sensor_offset,
                  "With --footprint-box: the sensor's position X,Y (m) from the box's centre, x "
                  "forward, y left (default 0,0)")
      ->delimiter(',')
      ->expected(2);
  cmd->add_option("--poses", o->poses,
                  "Build the maps with these poses (KITTI poses.txt) instead of the sequence's; "
                  "the driven cells and truths stay the sequence's (e.g. simulate --pose-noise)");
  cmd->add_option("--traffic", o->traffic,
                  "traffic.json of bgkmap simulate with moving objects (default: "
                  "<sequence>/traffic.json if present): also score stale trails and missed new "
                  "obstacles");
  cmd->add_option("--trail-scans", o->trail_scans,
                  "Scans after a vehicle left a cell that its trail is judged on (default 5)");
  cmd->add_option("--new-obstacle-scans", o->new_scans,
                  "Scans after a vehicle arrived that it must be shown on (default 1)");
  cmd->add_option("--figure-scans", o->figure_scans,
                  "With a footprint: also draw the driven cells' figure on the map after these "
                  "scans, 30 m around the sensor (drive_<method>_scanK.png)")
      ->delimiter(',');
  cmd->add_option("--trace", o->trace,
                  "With a footprint: write every driven cell's statistics after every scan to "
                  "<out>/<method>_FILE (CSV), for diagnosis")
      ->group("");
  cmd->add_option("--pose-noise", o->pose_noise,
                  "Perturb the mapping poses like a real SLAM's error at this scale (1: 3 cm and "
                  "0.1 deg per scan, plus a slow drift of 5 cm in z and 0.2 deg in roll and "
                  "pitch; sim/pose_noise.h); the driven cells and truths stay the sequence's");
  cmd->add_option("--pose-noise-seed", o->pose_noise_seed, "Seed of --pose-noise (default 1)");
  cmd->add_option("--pose-noise-parts", o->pose_noise_parts,
                  "Keep only these components of --pose-noise: xy, z, tilt (roll and pitch), yaw, "
                  "drift (default: all)")
      ->delimiter(',');
  cmd->add_flag("--align-z", o->align_z,
                "Align each scan's z to the map built so far before integrating it, as a robot's "
                "localization would (core/vertical_alignment.h; docs/mapping-your-robot.md, "
                "\"Vertical alignment\"): the odd, even and real-time maps each to their own");
  cmd->add_option("--align-tilt", o->align.max_tilt_deg,
                  "With --align-z: also level each scan's roll and pitch against the map, up to "
                  "this many degrees (default 0: off; docs/mapping-your-robot.md, \"Levelling the "
                  "tilt\")");
  cmd->add_option("--align-z-radius", o->align.radius_m,
                  "With --align-z: compare the cells within this distance of the sensor (m, "
                  "default 20)");
  cmd->add_flag("!--no-odd-even", o->odd_even,
                "With a footprint, skip the odd scans' map against the even scans' map");
  cmd->callback([o, &exit_code] { exit_code = RunEval(*o); });
}

}  // namespace bgkmap::cli
