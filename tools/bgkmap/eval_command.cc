// `bgkmap eval`: maps a simulated sequence with each method and scores it against the ground
// truth (coverage, elevation MSE, ROC/AUC, stage times, scans skipped at the scan rate). With a
// changes.json (`bgkmap simulate --change`), also the stale-obstacle and missed-new-obstacle
// rates per scan after each change (eval/change_score.h).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/change_score.h"
#include "bgkmap/eval/map_score.h"
#include "bgkmap/eval/realtime_gate.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/progress_bar.h"
#include "commands.h"
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
};

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
};

// Integrates the scans with admitted[k] (all if empty), timing each one; after_scan(k, map), if
// given, looks at the map after scan k (outside the timings).
Result<Run> MapScans(const MapParams& params, const std::vector<SourceScan>& scans,
                     const std::vector<bool>& admitted, const std::string& label,
                     const std::function<void(size_t, const TerrainMap&)>& after_scan = {}) {
  Result<std::unique_ptr<TerrainMap>> created = TerrainMap::Create(params);
  if (!created.ok()) return created.status();
  Run run;
  run.map = std::move(created).value();
  io::ProgressBar progress(label, scans.size(), "scans");
  for (size_t k = 0; k < scans.size(); ++k) {
    progress.Add();
    if (!admitted.empty() && !admitted[k]) continue;
    const auto t0 = Clock::now();
    Result<ScanReport> r =
        run.map->IntegrateScan(scans[k].points, scans[k].pose, scans[k].frame_is_map);
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

Raster FigureLayers(const TerrainMap& map, const Raster& truth) {
  return ExtractRaster(map, truth.box, {Layer::kState, Layer::kTraversabilityVariance});
}

int RunEval(const EvalOptions& o) {
  namespace fs = std::filesystem;
  const auto start = Clock::now();
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  MapParams params = *loaded;
  if (!(o.rate_hz > 0)) return Usage("--rate must be > 0");
  std::vector<Method> methods;
  for (const std::string& name : o.methods) {
    Result<Method> m = ParseMethod(name);
    if (!m.ok()) return Usage(m.status().message());
    methods.push_back(*m);
  }
  Result<Raster> truth = io::ReadGeoTiff(o.truth);
  if (!truth.ok()) return Fail(truth.status().message());
  if (truth->Find(Layer::kState) == nullptr || truth->Find(Layer::kElevation) == nullptr) {
    return Fail(o.truth + ": ground truth needs elevation and state bands");
  }
  if (truth->stride != 1 || std::abs(truth->resolution - params.resolution) > 1e-9) {
    return Fail(o.truth + ": ground truth resolution " + std::to_string(truth->resolution) +
                " m differs from the map resolution " + std::to_string(params.resolution) + " m");
  }
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.sequence);
  if (!source.ok()) return Fail(source.status().message());
  std::vector<SourceScan> scans;  // read up front: file I/O is no part of the timings
  for (size_t k = 0; k < (*source)->size(); ++k) {
    Result<SourceScan> s = (*source)->Read(k);
    if (!s.ok()) return Fail(s.status().message());
    scans.push_back(std::move(s).value());
  }
  if (o.change_scans < 1) return Usage("--change-scans must be at least 1");
  std::vector<Change> changes;
  std::error_code ec;
  const std::string changes_path =
      !o.changes.empty() ? o.changes : (fs::path(o.sequence) / "changes.json").string();
  if (!o.changes.empty() || fs::exists(changes_path, ec)) {
    Result<std::vector<Change>> loaded_changes = LoadChanges(changes_path, params);
    if (!loaded_changes.ok()) return Fail(loaded_changes.status().message());
    changes = std::move(loaded_changes).value();
  }
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());

  EvalReport report;
  report.name = o.name;
  report.sequence = o.sequence;
  report.rate_hz = o.rate_hz;
  report.params = params;
  report.has_changes = !changes.empty();
  for (Method method : methods) {
    MapParams p = params;
    p.method = method;
    const std::string name(MethodName(method));
    MethodResult m;
    // The changes, scored on the map after each scan from just before a change (j = 0) to
    // --change-scans after it.
    const size_t points = static_cast<size_t>(o.change_scans) + 1;
    if (!changes.empty()) {
      m.removed.resize(points);
      m.appeared.resize(points);
    }
    auto score_changes = [&](size_t k, const TerrainMap& map) {
      for (const Change& c : changes) {
        const long j = static_cast<long>(k) + 1 - c.scan;  // scans of the changed world mapped
        if (j < 0 || j >= static_cast<long>(points)) continue;
        (c.kind == eval::ChangeKind::kRemoved ? m.removed : m.appeared)[static_cast<size_t>(j)] +=
            eval::ScoreChange(map, c.cells, c.kind);
      }
    };
    Result<Run> offline = MapScans(p, scans, {}, name + " (all scans)", score_changes);
    if (!offline.ok()) return Fail(name + ": " + offline.status().message());
    m.method = method;
    m.scans = scans.size();
    const double n = static_cast<double>(scans.size());
    m.prepare_s = offline->prepare / n;
    m.elevation_s = offline->sum.elevation / n;
    m.features_s = offline->sum.features / n;
    m.traversability_s = offline->sum.traversability / n;
    m.max_scan_s = offline->max_scan;
    m.offline = eval::ScoreMap(*offline->map, *truth);

    // Real time: replay the measured timings through the two-process gate, then map only the
    // scans it admits (their own timings differ slightly: the map they meet is sparser).
    const std::vector<bool> admitted = eval::AdmitScans(offline->timings, 1.0 / o.rate_hz);
    for (bool a : admitted) m.skipped += a ? 0 : 1;
    if (m.skipped == 0) {
      m.realtime = m.offline;
      m.maps = FigureLayers(*offline->map, *truth);
    } else {
      Result<Run> realtime = MapScans(p, scans, admitted, name + " (real time)");
      if (!realtime.ok()) return Fail(name + ": " + realtime.status().message());
      m.realtime = eval::ScoreMap(*realtime->map, *truth);
      m.maps = FigureLayers(*realtime->map, *truth);
    }
    report.methods.push_back(std::move(m));
  }

  auto write = [&](const std::string& file, const std::string& text) {
    std::ofstream f(fs::path(o.out) / file);
    f << text;
    return static_cast<bool>(f);
  };
  if (!write("eval.json", ToJson(report))) return Fail(o.out + "/eval.json: cannot write");
  const std::string table = ToMarkdown(report);
  if (!write("table.md", table)) return Fail(o.out + "/table.md: cannot write");
  if (o.figures) {
    std::string note;
    if (Status s = WriteFigures(report, *truth, o.out, &note); !s.ok()) return Fail(s.message());
    if (!note.empty()) std::fprintf(stderr, "bgkmap eval: %s\n", note.c_str());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("%s\nbgkmap eval: %s, %zu scans, %zu methods, %.1f s -> %s\n", table.c_str(),
              o.name.c_str(), scans.size(), methods.size(), seconds, o.out.c_str());
  return 0;
}

}  // namespace

void RegisterEvalCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Score the mapping methods on a simulated sequence against its ground truth");
  cmd->add_option("sequence", o->sequence, "KITTI-like directory (from bgkmap simulate)")
      ->required();
  cmd->add_option("--truth", o->truth,
                  "Ground-truth GeoTIFF (default: <sequence>/ground_truth.tif)");
  cmd->add_option("--config", o->config, "YAML map parameters (the ground truth's)");
  cmd->add_option("--out", o->out, "Output directory for eval.json, table.md and figures")
      ->required();
  cmd->add_option("--name", o->name, "Dataset name in tables and figures");
  cmd->add_option("--methods", o->methods, "Methods to compare (default: all six)")->delimiter(',');
  cmd->add_option("--rate", o->rate_hz, "Scan rate for the real-time replay, Hz (default 10)");
  cmd->add_flag("!--no-figures", o->figures, "Skip the gnuplot figures");
  cmd->add_option("--changes", o->changes,
                  "changes.json of bgkmap simulate --change (default: <sequence>/changes.json if "
                  "present): also score stale and missed obstacles per scan after each change");
  cmd->add_option("--change-scans", o->change_scans,
                  "Scans after each change to score (default 10)");
  cmd->callback([o, &exit_code] {
    if (o->truth.empty())
      o->truth = (std::filesystem::path(o->sequence) / "ground_truth.tif").string();
    exit_code = RunEval(*o);
  });
}

}  // namespace bgkmap::cli
