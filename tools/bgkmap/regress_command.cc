// `bgkmap regress`: the paper's Fig. 1 protocol on a cloud (a LAS with class filtering, or every
// point of any scan source in the map frame). Points are split at random into a training and a
// test half; BGK elevation regression (kernel length and
// resolution picked by cross-validation on the training half only) and GDAL's gdal_grid
// (invdist, invdistnn, linear) grid the training half on the same cells; each is scored by the
// RMSE at the test points (value of the cell containing the point) and its wall time.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "commands.h"
#include "gdal_grid_runner.h"
#include "json_output.h"
#include "scan_source.h"

namespace bgkmap::cli {
namespace {

using Clock = std::chrono::steady_clock;
using P3 = std::array<double, 3>;
using Json = nlohmann::ordered_json;

struct RegressOptions {
  std::string input;
  std::string out;
  std::vector<int> classes = {2};
  uint64_t seed = 1;
  int folds = 5;
  // The cross-validation grid (a kernel length below the resolution is skipped).
  std::vector<double> resolutions = {0.5, 1.0, 2.0};
  std::vector<double> kernel_lengths = {1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0};
  std::vector<std::string> peers = {"invdist", "invdistnn", "linear"};
  // The BGK methods, each with its own cross-validation: the paper's ("bgk", method bgk+) and
  // the local-linear one (bgk-ll).
  std::vector<std::string> methods = {"bgk+", "bgk-ll"};
};

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap regress: %s\n", msg.c_str());
  return kExitFailure;
}

// A bad command line: the same line, exit code kExitUsage.
int Usage(const std::string& msg) {
  Fail(msg);
  return kExitUsage;
}

double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

MapParams RegressionParams(Method method, double resolution, double kernel_length) {
  MapParams p;
  p.resolution = resolution;
  p.kernel_length = kernel_length;
  p.observation = Observation::kMean;  // ground points of one cell: their mean height
  p.method = method;
  p.robot_radius = std::max(p.robot_radius, resolution);  // unused here, but must span a cell
  return p;
}

// Null if the parameters do not validate.
std::unique_ptr<TerrainMap> Fit(const MapParams& params, const std::vector<P3>& pts) {
  std::vector<Point3f> cloud;
  cloud.reserve(pts.size());
  for (const P3& p : pts) {
    cloud.push_back({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
  }
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params);
  if (!map.ok() || !(*map)->IntegrateScan(cloud, Pose{}, /*frame_is_map=*/true).ok())
    return nullptr;
  return std::move(map).value();
}

// Every point of the source in the map frame (LAS: of the chosen classes).
Result<std::vector<P3>> ReadMapFramePoints(const std::string& path, const SourceOptions& so) {
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(path, so);
  if (!source.ok()) return source.status();
  std::vector<P3> pts;
  for (size_t k = 0; k < (*source)->size(); ++k) {
    Result<SourceScan> scan = (*source)->Read(k);
    if (!scan.ok()) return scan.status();
    const Pose& T = scan->pose;
    for (const Point3f& p : scan->points) {
      // A single cloud has an identity rotation and its origin in the translation.
      const Eigen::Vector3d q = T.rotation * Eigen::Vector3d(p.x, p.y, p.z) + T.translation;
      if (q.allFinite()) pts.push_back({q.x(), q.y(), q.z()});
    }
  }
  return pts;
}

struct Score {
  double rmse = std::numeric_limits<double>::quiet_NaN();
  double coverage = 0;  // fraction of points with a prediction
};

template <typename Predict>
Score ScorePoints(const std::vector<P3>& pts, Predict predict,
                  const std::vector<bool>* only = nullptr) {
  double se = 0;
  size_t n = 0, total = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (only && !(*only)[i]) continue;
    ++total;
    const double z = predict(pts[i][0], pts[i][1]);
    if (std::isnan(z)) continue;
    se += (z - pts[i][2]) * (z - pts[i][2]);
    ++n;
  }
  Score s;
  if (n) s.rmse = std::sqrt(se / n);
  s.coverage = total ? static_cast<double>(n) / total : 0;
  return s;
}

struct Candidate {
  double resolution, kernel_length;
  Score cv;
};

// The selection rule: k-fold cross-validation on the training half over a fixed grid; the
// lowest CV RMSE among candidates that predict at least 99% of held-out points wins.
Candidate SelectByCrossValidation(Method method, const std::vector<P3>& train,
                                  const RegressOptions& o, std::vector<Candidate>* all) {
  const int folds = o.folds;
  for (double res : o.resolutions) {
    for (double l : o.kernel_lengths) {
      if (l < res) continue;
      double se = 0;
      size_t n = 0, total = 0;
      for (int f = 0; f < folds; ++f) {
        std::vector<P3> fit, held;
        for (size_t i = 0; i < train.size(); ++i)
          (static_cast<int>(i % folds) == f ? held : fit).push_back(train[i]);
        const auto map = Fit(RegressionParams(method, res, l), fit);
        if (!map) continue;
        for (const P3& p : held) {
          ++total;
          const double z = map->EstimateAt(p[0], p[1]).elevation;
          if (std::isnan(z)) continue;
          se += (z - p[2]) * (z - p[2]);
          ++n;
        }
      }
      Candidate c{res, l, {}};
      c.cv.rmse = n ? std::sqrt(se / n) : std::numeric_limits<double>::infinity();
      c.cv.coverage = total ? static_cast<double>(n) / total : 0;
      all->push_back(c);
    }
  }
  const Candidate* best = nullptr;
  for (const Candidate& c : *all) {
    if (c.cv.coverage >= 0.99 && (!best || c.cv.rmse < best->cv.rmse)) best = &c;
  }
  if (!best) {  // nothing predicts 99%: the candidate that predicts most
    for (const Candidate& c : *all) {
      if (!best || c.cv.coverage > best->cv.coverage) best = &c;
    }
  }
  return *best;
}

struct Row {
  std::string method, params;
  Score test, common;
  double seconds;
};

int RunRegress(const RegressOptions& o) {
  namespace fs = std::filesystem;
  if (o.folds < 2) return Usage("--folds must be at least 2");
  if (o.resolutions.empty() || o.kernel_lengths.empty())
    return Usage("--resolutions and --kernel-lengths need at least one value");
  for (double v : o.resolutions) {
    if (!(v > 0)) return Usage("--resolutions: every value must be > 0");
  }
  for (const std::string& peer : o.peers) {
    if (peer != "invdist" && peer != "invdistnn" && peer != "linear" && peer != "none")
      return Usage("--peers: unknown gdal_grid method '" + peer + "' (invdist, invdistnn, linear)");
  }
  SourceOptions so;
  for (int c : o.classes) {
    if (c < 0 || c > 255) return Usage("--classes: a LAS class is 0..255");
    so.las_classes.push_back(static_cast<uint8_t>(c));
  }
  Result<std::vector<P3>> read = ReadMapFramePoints(o.input, so);
  if (!read.ok()) return Fail(read.status().message());
  std::vector<P3>& all = *read;
  if (all.size() < 100) return Fail(o.input + ": fewer than 100 points (of the classes)");
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());

  // Local frame: floats keep millimetres; the same coordinates go to gdal_grid.
  double ox = 1e300, oy = 1e300;
  for (const P3& p : all) ox = std::min(ox, p[0]), oy = std::min(oy, p[1]);
  ox = std::floor(ox);
  oy = std::floor(oy);
  std::vector<P3> pts;
  pts.reserve(all.size());
  for (const P3& p : all) pts.push_back({p[0] - ox, p[1] - oy, p[2]});
  all = {};
  std::mt19937_64 rng(o.seed);
  std::shuffle(pts.begin(), pts.end(), rng);
  const std::vector<P3> train(pts.begin(), pts.begin() + pts.size() / 2);
  const std::vector<P3> test(pts.begin() + pts.size() / 2, pts.end());

  // Each BGK method: its own cross-validation on the training half, then a fit on all of it.
  struct Fitted {
    Method method;
    std::vector<Candidate> candidates;
    Candidate chosen;
    double cv_seconds;
    std::unique_ptr<TerrainMap> map;
  };
  std::vector<Fitted> fitted;
  std::vector<Row> rows;
  char buf[128];
  for (const std::string& name : o.methods) {
    Result<Method> method = ParseMethod(name);
    if (!method.ok()) return Usage("--methods: " + method.status().message());
    Fitted f{*method, {}, {}, 0, nullptr};
    const auto tcv = Clock::now();
    f.chosen = SelectByCrossValidation(f.method, train, o, &f.candidates);
    f.cv_seconds = Seconds(tcv);
    const MapParams params =
        RegressionParams(f.method, f.chosen.resolution, f.chosen.kernel_length);
    const auto t0 = Clock::now();
    f.map = Fit(params, train);
    if (!f.map) return Fail("BGK regression failed for the chosen parameters");
    const Raster raster = ExtractRaster(*f.map, f.map->KnownBounds(), {Layer::kElevation});
    const double seconds = Seconds(t0);
    const TerrainMap& m = *f.map;
    std::snprintf(buf, sizeof buf, "l = %g m, res = %g m", f.chosen.kernel_length,
                  f.chosen.resolution);
    rows.push_back(
        {f.method == Method::kBgkPlus ? "bgk" : name,
         buf,
         ScorePoints(test,
                     [&m](double x, double y) -> double { return m.EstimateAt(x, y).elevation; }),
         {},
         seconds});
    fitted.push_back(std::move(f));
  }
  if (fitted.empty()) return Usage("--methods: name at least one BGK method");

  // gdal_grid on the same training CSV, on the grid of each resolution a BGK method chose.
  const std::string csv = (fs::path(o.out) / "train.csv").string();
  if (Status s = WritePointsCsv(csv, train); !s.ok()) return Fail(s.message());
  std::vector<double> resolutions;
  for (const Fitted& f : fitted) {
    if (std::find(resolutions.begin(), resolutions.end(), f.chosen.resolution) == resolutions.end())
      resolutions.push_back(f.chosen.resolution);
  }
  std::vector<SampledGrid> grids;
  double x1 = 0, y1 = 0;  // the extent of every point (not the test values)
  for (const P3& p : pts) x1 = std::max(x1, p[0]), y1 = std::max(y1, p[1]);
  for (double res : resolutions) {
    const GridGeometry geo(res, MapParams{}.tile_size);
    const CellBox box = geo.BoxCovering(0, 0, x1, y1);
    const GridExtent extent{box.min.x * res,
                            box.min.y * res,
                            (box.max.x + 1) * res,
                            (box.max.y + 1) * res,
                            static_cast<int>(box.width()),
                            static_cast<int>(box.height())};
    // invdistnn searches as far as the first method's kernel reaches.
    std::snprintf(buf, sizeof buf, "invdistnn:power=2.0:radius=%g:max_points=12",
                  fitted.front().chosen.kernel_length);
    std::vector<std::pair<std::string, std::string>> peers;
    for (const std::string& peer : o.peers) {
      if (peer == "invdist") peers.push_back({"gdal invdist", "invdist:power=2.0"});
      if (peer == "invdistnn") peers.push_back({"gdal invdistnn", buf});
      if (peer == "linear") peers.push_back({"gdal linear", "linear"});
    }
    std::string at, suffix;  // in the table, in the file name
    if (resolutions.size() > 1) {
      char r[32];
      std::snprintf(r, sizeof r, " @ %g m", res);
      at = r;
      std::snprintf(r, sizeof r, "_%gm", res);
      suffix = r;
    }
    for (const auto& [name, algo] : peers) {
      const std::string tif =
          (fs::path(o.out) / (algo.substr(0, algo.find(':')) + suffix + ".tif")).string();
      Result<SampledGrid> g = RunGdalGrid(csv, algo, extent, tif);
      if (!g.ok()) return Fail(g.status().message());
      const SampledGrid& grid = *g;
      rows.push_back(
          {name + at,
           algo,
           ScorePoints(test, [&](double x, double y) -> double { return grid.At(x, y); }),
           {},
           grid.seconds});
      grids.push_back(std::move(g).value());
    }
  }
  // The common test set: points every method predicts.
  std::vector<bool> common(test.size(), true);
  for (size_t i = 0; i < test.size(); ++i) {
    for (const Fitted& f : fitted)
      common[i] = common[i] && !std::isnan(f.map->EstimateAt(test[i][0], test[i][1]).elevation);
    for (const SampledGrid& g : grids)
      common[i] = common[i] && !std::isnan(g.At(test[i][0], test[i][1]));
  }
  for (size_t k = 0; k < fitted.size(); ++k) {
    const TerrainMap& m = *fitted[k].map;
    rows[k].common = ScorePoints(
        test, [&m](double x, double y) -> double { return m.EstimateAt(x, y).elevation; }, &common);
  }
  for (size_t k = 0; k < grids.size(); ++k) {
    const SampledGrid& g = grids[k];
    rows[fitted.size() + k].common = ScorePoints(
        test, [&](double x, double y) -> double { return g.At(x, y); }, &common);
  }
  const Candidate& chosen = fitted.front().chosen;
  const std::vector<Candidate>& candidates = fitted.front().candidates;
  const double cv_seconds = fitted.front().cv_seconds;

  std::ostringstream md;
  md << "| Method | Parameters | Test RMSE (m) | Test points predicted (%) | RMSE on common points "
        "(m) | "
        "Time (s) | RMSE / BGK | Time / BGK |\n|---|---|---|---|---|---|---|---|\n";
  for (const Row& r : rows) {
    char line[512];
    std::snprintf(line, sizeof line, "| %s | `%s` | %.4f | %.1f | %.4f | %.3f | %.2f | %.1f |\n",
                  r.method.c_str(), r.params.c_str(), r.test.rmse, 100 * r.test.coverage,
                  r.common.rmse, r.seconds, r.common.rmse / rows[0].common.rmse,
                  r.seconds / rows[0].seconds);
    md << line;
  }
  // The keys in the order they were always written (ordered_json); NaN/inf are null.
  const auto cv_table = [](const std::vector<Candidate>& scored) {
    Json table = Json::array();
    for (const Candidate& c : scored) {
      table.push_back({{"resolution", JsonNumber<Json>(c.resolution)},
                       {"kernel_length", JsonNumber<Json>(c.kernel_length)},
                       {"rmse", JsonNumber<Json>(c.cv.rmse)},
                       {"coverage", JsonNumber<Json>(c.cv.coverage)}});
    }
    return table;
  };
  Json cv = cv_table(candidates);
  Json results = Json::array();
  for (const Row& r : rows) {
    results.push_back({{"method", r.method},
                       {"parameters", r.params},
                       {"rmse", JsonNumber<Json>(r.test.rmse)},
                       {"coverage", JsonNumber<Json>(r.test.coverage)},
                       {"rmse_common", JsonNumber<Json>(r.common.rmse)},
                       {"seconds", JsonNumber<Json>(r.seconds)}});
  }
  Json js;
  js["input"] = o.input;
  js["points"] = pts.size();
  js["chosen"] = {{"resolution", JsonNumber<Json>(chosen.resolution)},
                  {"kernel_length", JsonNumber<Json>(chosen.kernel_length)},
                  {"cv_rmse", JsonNumber<Json>(chosen.cv.rmse)}};
  js["train"] = train.size();
  js["test"] = test.size();
  js["seed"] = o.seed;
  js["folds"] = o.folds;
  js["cv_seconds"] = JsonNumber<Json>(cv_seconds);
  js["cv"] = std::move(cv);
  js["results"] = std::move(results);
  // Every BGK method's own choice and CV table ("chosen" and "cv" above: the first's).
  Json per_method = Json::array();
  for (const Fitted& f : fitted) {
    per_method.push_back({{"method", std::string(MethodName(f.method))},
                          {"chosen",
                           {{"resolution", JsonNumber<Json>(f.chosen.resolution)},
                            {"kernel_length", JsonNumber<Json>(f.chosen.kernel_length)},
                            {"cv_rmse", JsonNumber<Json>(f.chosen.cv.rmse)}}},
                          {"cv_seconds", JsonNumber<Json>(f.cv_seconds)},
                          {"cv", cv_table(f.candidates)}});
  }
  js["methods"] = std::move(per_method);
  std::ofstream(fs::path(o.out) / "regress.json") << JsonText(js);
  std::ofstream(fs::path(o.out) / "table.md") << md.str();
  std::printf(
      "%s\nbgkmap regress: %zu points (%zu train, %zu test), %d-fold CV on the training "
      "half chose",
      md.str().c_str(), pts.size(), train.size(), test.size(), o.folds);
  for (const Fitted& f : fitted) {
    std::printf(" %s: l = %g m, res = %g m (CV RMSE %.4f m, %.1f s);",
                std::string(MethodName(f.method)).c_str(), f.chosen.kernel_length,
                f.chosen.resolution, f.chosen.cv.rmse, f.cv_seconds);
  }
  std::printf(" -> %s\n", o.out.c_str());
  return 0;
}

}  // namespace

void RegisterRegressCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<RegressOptions>();
  CLI::App* cmd = app.add_subcommand(
      "regress",
      "Fig. 1 protocol: BGK elevation regression vs gdal_grid on a 50/50 split of a LAS");
  cmd->add_option("input", o->input,
                  "LAS file, or any scan source (directory, .graph, .pcd): all points in the map "
                  "frame")
      ->required();
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->add_option("--classes", o->classes, "LAS classes to use (default 2, ground)")
      ->delimiter(',');
  cmd->add_option("--seed", o->seed, "Seed of the random split (default 1)");
  cmd->add_option("--folds", o->folds, "Cross-validation folds on the training half (default 5)");
  cmd->add_option("--resolutions", o->resolutions, "Cross-validated resolutions, m (0.5,1,2)")
      ->delimiter(',');
  cmd->add_option("--kernel-lengths", o->kernel_lengths,
                  "Cross-validated kernel lengths, m (1,2,3,4,6,8,12)")
      ->delimiter(',');
  cmd->add_option("--peers", o->peers, "gdal_grid methods: invdist,invdistnn,linear or none")
      ->delimiter(',');
  cmd->add_option("--methods", o->methods,
                  "BGK methods, each cross-validated on its own (default bgk+,bgk-ll)")
      ->delimiter(',');
  cmd->callback([o, &exit_code] { exit_code = RunRegress(*o); });
}

}  // namespace bgkmap::cli
