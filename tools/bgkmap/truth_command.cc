// `bgkmap truth`: a ground truth for a real scan sequence, from ALL points of ALL its scans
// (eval/scan_truth.h), for `bgkmap eval --truth` to score maps made from a sparser part of the
// sequence (`bgkmap thin`). docs/results.md, "Real street scans (issue 14 protocol)".
//   <out>/ground_truth.tif   elevation, traversability, state (the simulator's band layout)
//   <out>/truth.json         the parameters, the support rule and the counts
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/eval/scan_truth.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/progress_bar.h"
#include "commands.h"
#include "json_output.h"
#include "scan_source.h"

namespace bgkmap::cli {
namespace {

struct TruthOptions {
  std::string sequence;
  std::string config;
  std::string out;
  int min_points = eval::ScanTruthOptions{}.min_points;
};

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap truth: %s\n", msg.c_str());
  return kExitFailure;
}

int RunTruth(const TruthOptions& o) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  const MapParams params = *loaded;
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.sequence);
  if (!source.ok()) return Fail(source.status().message());
  eval::ScanTruthOptions options;
  options.min_points = o.min_points;
  eval::ScanTruthBuilder builder(params, options);
  {
    io::ProgressBar progress("truth from all points", (*source)->size(), "scans");
    for (size_t k = 0; k < (*source)->size(); ++k) {
      Result<SourceScan> s = (*source)->Read(k);
      if (!s.ok()) return Fail(s.status().message());
      if (Status st = builder.AddScan(s->points, s->pose, s->frame_is_map); !st.ok()) {
        return Fail("scan " + std::to_string(k) + ": " + st.message());
      }
      progress.Add();
    }
  }
  const Raster truth = builder.Build();
  const eval::ScanTruthStats stats = builder.Stats(truth);
  if (stats.judged_cells == 0) {
    return Fail(o.sequence + ": no cell has enough points for a ground truth");
  }
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());
  const std::string truth_path = (fs::path(o.out) / "ground_truth.tif").string();
  if (Status s = io::WriteGeoTiff(truth, truth_path); !s.ok()) return Fail(s.message());

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  using Json = nlohmann::ordered_json;
  Json j;
  j["sequence"] = o.sequence;
  j["config"] = o.config;
  j["resolution"] = JsonNumber<Json>(params.resolution);
  j["robot_radius"] = JsonNumber<Json>(params.robot_radius);
  j["observation"] = std::string(ObservationName(params.observation));
  j["min_points"] = o.min_points;
  j["scans"] = stats.scans;
  j["points_input"] = stats.points_input;
  j["points_kept"] = stats.points_kept;
  j["observed_cells"] = stats.observed_cells;
  j["supported_cells"] = stats.supported_cells;
  j["judged_cells"] = stats.judged_cells;
  j["traversable_cells"] = stats.traversable_cells;
  j["non_traversable_cells"] = stats.non_traversable_cells;
  j["seconds"] = JsonNumber<Json>(seconds);
  std::ofstream js(fs::path(o.out) / "truth.json");
  js << JsonText(j);
  if (!js) return Fail(o.out + "/truth.json: cannot write");
  std::printf(
      "bgkmap truth: %llu scans, %llu of %llu points kept, %lld cells observed, %lld with >= %d "
      "points, %lld judged (%lld traversable, %lld not), %.1f s -> %s\n",
      static_cast<unsigned long long>(stats.scans),
      static_cast<unsigned long long>(stats.points_kept),
      static_cast<unsigned long long>(stats.points_input),
      static_cast<long long>(stats.observed_cells), static_cast<long long>(stats.supported_cells),
      o.min_points, static_cast<long long>(stats.judged_cells),
      static_cast<long long>(stats.traversable_cells),
      static_cast<long long>(stats.non_traversable_cells), seconds, truth_path.c_str());
  return 0;
}

}  // namespace

void RegisterTruthCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<TruthOptions>();
  CLI::App* cmd = app.add_subcommand(
      "truth", "Build a ground truth for a real scan sequence from all points of all its scans");
  cmd->add_option("sequence", o->sequence, "KITTI-like directory (or a scan graph, LAS, PCD)")
      ->required();
  cmd->add_option("--config", o->config,
                  "YAML map parameters (resolution, observation, filters, robot radius, "
                  "traversability): those of the maps to be scored");
  cmd->add_option("--out", o->out, "Output directory for ground_truth.tif and truth.json")
      ->required();
  cmd->add_option("--min-points", o->min_points,
                  "Points a cell needs over all scans to be part of the truth (default 2)")
      ->check(CLI::Range(1, 1000000));
  cmd->callback([o, &exit_code] { exit_code = RunTruth(*o); });
}

}  // namespace bgkmap::cli
