// `bgkmap eval`: maps a simulated sequence with each method and scores it against the ground
// truth (coverage, elevation MSE, ROC/AUC, stage times, scans skipped at the scan rate).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/map_score.h"
#include "bgkmap/eval/realtime_gate.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/progress_bar.h"
#include "commands.h"
#include "eval_report.h"
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
  std::vector<std::string> methods = {"baseline", "bgk-trav", "bgk+", "one-step", "bgk-obstacle"};
  double rate_hz = 10.0;
  bool figures = true;
};

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

// Integrates the scans with admitted[k] (all if empty), timing each one.
Result<Run> MapScans(const MapParams& params, const std::vector<SourceScan>& scans,
                     const std::vector<bool>& admitted, const std::string& label) {
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
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());

  EvalReport report;
  report.name = o.name;
  report.sequence = o.sequence;
  report.rate_hz = o.rate_hz;
  report.params = params;
  for (Method method : methods) {
    MapParams p = params;
    p.method = method;
    const std::string name(MethodName(method));
    Result<Run> offline = MapScans(p, scans, {}, name + " (all scans)");
    if (!offline.ok()) return Fail(name + ": " + offline.status().message());
    MethodResult m;
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
  cmd->add_option("--methods", o->methods, "Methods to compare (default: all five)")
      ->delimiter(',');
  cmd->add_option("--rate", o->rate_hz, "Scan rate for the real-time replay, Hz (default 10)");
  cmd->add_flag("!--no-figures", o->figures, "Skip the gnuplot figures");
  cmd->callback([o, &exit_code] {
    if (o->truth.empty())
      o->truth = (std::filesystem::path(o->sequence) / "ground_truth.tif").string();
    exit_code = RunEval(*o);
  });
}

}  // namespace bgkmap::cli
