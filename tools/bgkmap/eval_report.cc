#include "eval_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "json_output.h"

namespace bgkmap::cli {
namespace {

std::string Num(double v, const char* fmt = "%.6g") {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string Cell(double v, const char* fmt) { return std::isfinite(v) ? Num(v, fmt) : "n/a"; }

using Json = nlohmann::ordered_json;  // keys in the order eval.json always had

Json ScoreJson(const eval::MapScore& s) {
  return {{"truth_cells", s.truth_cells},
          {"known_cells", s.known_cells},
          {"coverage", JsonNumber<Json>(s.coverage)},
          {"mse_all_m2", JsonNumber<Json>(s.mse_all)},
          {"mse_ground_m2", JsonNumber<Json>(s.mse_ground)},
          {"auc", JsonNumber<Json>(s.roc.auc)},
          {"roc_positives", s.roc.positives},
          {"roc_negatives", s.roc.negatives},
          {"state_accuracy", JsonNumber<Json>(s.state_accuracy)},
          {"dangerous_misses", s.dangerous_misses},
          {"dangerous_miss_rate", JsonNumber<Json>(s.dangerous_miss_rate)},
          {"false_alarms", s.false_alarms},
          {"false_alarm_rate", JsonNumber<Json>(s.false_alarm_rate)}};
}

Json ChangeJson(const std::vector<eval::ChangeCounts>& curve, const char* wrong) {
  Json points = Json::array();
  for (size_t j = 0; j < curve.size(); ++j) {
    const eval::ChangeCounts& c = curve[j];
    Json p;
    p["scans_after"] = j;
    p["judged_cells"] = c.judged;
    p[std::string(wrong) + "_cells"] = c.wrong;
    p["unknown_cells"] = c.unknown;
    p[std::string(wrong) + "_rate"] = JsonNumber<Json>(c.rate());
    points.push_back(std::move(p));
  }
  return points;
}

}  // namespace

std::string ToJson(const EvalReport& r) {
  Json methods = Json::array();
  for (const MethodResult& m : r.methods) {
    Json change;
    if (r.has_changes) {
      change["removed"] = ChangeJson(m.removed, "stale");
      change["appeared"] = ChangeJson(m.appeared, "missed");
    }
    methods.push_back({{"method", std::string(MethodName(m.method))},
                       {"scans", m.scans},
                       {"skipped", m.skipped},
                       {"mean_prepare_s", JsonNumber<Json>(m.prepare_s)},
                       {"mean_elevation_s", JsonNumber<Json>(m.elevation_s)},
                       {"mean_features_s", JsonNumber<Json>(m.features_s)},
                       {"mean_traversability_s", JsonNumber<Json>(m.traversability_s)},
                       {"max_scan_s", JsonNumber<Json>(m.max_scan_s)},
                       {"realtime", ScoreJson(m.realtime)},
                       {"offline", ScoreJson(m.offline)}});
    if (r.has_changes) methods.back()["change"] = std::move(change);
  }
  Json j;
  j["dataset"] = r.name;
  j["sequence"] = r.sequence;
  j["rate_hz"] = JsonNumber<Json>(r.rate_hz);
  j["resolution"] = JsonNumber<Json>(r.params.resolution);
  j["kernel_length"] = JsonNumber<Json>(r.params.kernel_length);
  j["methods"] = std::move(methods);
  return JsonText(j);
}

std::string ToMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "| Dataset | Method | Coverage (%) | Skipped scans | Elevation (s) | Trav. calculation (s) "
       "| "
       "Trav. inference (s) | MSE all (m^2) | MSE ground (m^2) | AUC | "
       "Dangerous miss (%) | False alarm (%) | Offline coverage (%) | Offline AUC |\n"
    << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    const bool infers_elev = InfersElevation(m.method),
               infers_trav = InfersTraversability(m.method);
    o << "| " << r.name << " | " << MethodName(m.method) << " | "
      << Cell(100 * m.realtime.coverage, "%.1f") << " | " << m.skipped << "/" << m.scans << " | "
      << Cell(m.prepare_s + m.elevation_s, "%.4f") << (infers_elev ? "" : " (raw)") << " | "
      << Cell(m.features_s, "%.4f") << " | "
      << (infers_trav ? Cell(m.traversability_s, "%.4f") : std::string("N/A")) << " | "
      << Cell(m.realtime.mse_all, "%.4f") << " | " << Cell(m.realtime.mse_ground, "%.2e") << " | "
      << Cell(m.realtime.roc.auc, "%.4f") << " | "
      << Cell(100 * m.realtime.dangerous_miss_rate, "%.2f") << " | "
      << Cell(100 * m.realtime.false_alarm_rate, "%.2f") << " | "
      << Cell(100 * m.offline.coverage, "%.1f") << " | " << Cell(m.offline.roc.auc, "%.4f")
      << " |\n";
  }
  if (!r.has_changes) return o.str();
  // The changing world: per scan after the change, the share of the judged cells of removed
  // objects the map still shows (stale) and of appeared objects it does not show (missed).
  o << "\n| Dataset | Method | Scans after change | Stale obstacle (%) | Removed: judged cells | "
       "Missed new obstacle (%) | Missed: unknown (%) | Appeared: judged cells |\n"
    << "|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    const size_t n = std::max(m.removed.size(), m.appeared.size());
    for (size_t j = 0; j < n; ++j) {
      const eval::ChangeCounts none;
      const eval::ChangeCounts& rm = j < m.removed.size() ? m.removed[j] : none;
      const eval::ChangeCounts& ap = j < m.appeared.size() ? m.appeared[j] : none;
      const double unknown =
          ap.judged ? static_cast<double>(ap.unknown) / static_cast<double>(ap.judged) : NAN;
      o << "| " << r.name << " | " << MethodName(m.method) << " | " << j << " | "
        << Cell(100 * rm.rate(), "%.1f") << " | " << rm.judged << " | "
        << Cell(100 * ap.rate(), "%.1f") << " | " << Cell(100 * unknown, "%.1f") << " | "
        << ap.judged << " |\n";
    }
  }
  return o.str();
}

Status WriteFigures(const EvalReport& r, const Raster& truth, const std::string& dir,
                    std::string* note) {
  namespace fs = std::filesystem;
  auto path = [&](const std::string& f) { return (fs::path(dir) / f).string(); };
  auto write_bin = [&](const std::string& f, const std::vector<float>& v) {
    std::ofstream out(path(f), std::ios::binary);
    out.write(reinterpret_cast<const char*>(v.data()),
              static_cast<std::streamsize>(v.size() * sizeof(float)));
    return static_cast<bool>(out);
  };

  // ROC curves, one gnuplot data block per method.
  {
    std::ofstream roc(path("roc.dat"));
    for (const MethodResult& m : r.methods) {
      roc << "# " << MethodName(m.method) << "\n";
      for (const eval::RocPoint& p : eval::Thin(m.realtime.roc.curve, 400)) {
        roc << p.fpr << " " << p.tpr << "\n";
      }
      roc << "\n\n";
    }
    if (!roc) return Status::IoError(path("roc.dat") + ": cannot write");
  }
  std::ofstream gp(path("figures.gp"));
  gp << "set terminal png size 640,560\nset output '" << path("roc.png") << "'\n"
     << "set title '" << r.name << ": ROC of traversability (positive = non-traversable)'\n"
     << "set xlabel 'false positive rate'\nset ylabel 'true positive rate'\n"
     << "set key bottom right\nset xrange [0:1]\nset yrange [0:1]\nset size square\nplot ";
  for (size_t i = 0; i < r.methods.size(); ++i) {
    const MethodResult& m = r.methods[i];
    gp << (i ? ", " : "") << "'" << path("roc.dat") << "' index " << i << " with lines lw 2 title '"
       << MethodName(m.method) << " (AUC " << Cell(m.realtime.roc.auc, "%.4f") << ")'";
  }
  gp << ", x with lines dt 2 lc rgb 'gray' notitle\n";

  // Maps: ground truth, then each method's state, then the bgk+ traversability variance.
  auto state_image = [](const std::vector<float>& s) {
    std::vector<float> out(s.size());
    for (size_t i = 0; i < s.size(); ++i) out[i] = std::isnan(s[i]) ? 0.0f : s[i];  // 0 unknown
    return out;
  };
  std::vector<std::pair<std::string, std::string>> panels;  // file, title
  if (!write_bin("maps_truth.bin", state_image(*truth.Find(Layer::kState)))) {
    return Status::IoError(path("maps_truth.bin") + ": cannot write");
  }
  panels.emplace_back("maps_truth.bin", "ground truth");
  const Raster* variance = nullptr;
  for (const MethodResult& m : r.methods) {
    const std::string f = "maps_" + std::string(MethodName(m.method)) + ".bin";
    if (!write_bin(f, state_image(*m.maps.Find(Layer::kState)))) {
      return Status::IoError(path(f) + ": cannot write");
    }
    panels.emplace_back(f, std::string(MethodName(m.method)));
    if (m.method == Method::kBgkPlus) variance = &m.maps;
  }
  const double w = truth.cols * truth.resolution, h = truth.rows * truth.resolution;
  const int npanels = static_cast<int>(panels.size()) + (variance ? 1 : 0);
  const int panel_px = 260;
  const int panel_h = static_cast<int>(std::min(900.0, panel_px * h / w + 80));
  gp << "reset\nset terminal png size " << npanels * panel_px << "," << panel_h << "\n"
     << "set output '" << path("maps.png") << "'\n"
     << "set multiplot layout 1," << npanels << " title '" << r.name
     << ": gray traversable, red non-traversable, black unknown'\n"
     << "unset xtics\nunset ytics\nunset colorbox\nset size ratio -1\n"
     << "set object 1 rectangle from graph 0,0 to graph 1,1 behind fc rgb 'black' fs solid\n";
  const std::string array =
      "binary array=(" + std::to_string(truth.cols) + "," + std::to_string(truth.rows) +
      ") format='%float32' flipy dx=" + Num(truth.resolution) + " dy=" + Num(truth.resolution);
  gp << "set palette defined (0 'black', 1 'gray70', 2 'red')\nset cbrange [0:2]\n";
  gp << "set xrange [0:" << w << "]\nset yrange [0:" << h << "]\n";
  for (const auto& [file, title] : panels) {
    gp << "set title '" << title << "'\nplot '" << path(file) << "' " << array
       << " with image notitle\n";
  }
  if (variance) {
    if (!write_bin("maps_variance.bin", *variance->Find(Layer::kTraversabilityVariance))) {
      return Status::IoError(path("maps_variance.bin") + ": cannot write");
    }
    gp << "set title 'bgk+ variance'\nset palette defined (0 'white', 1 'magenta')\n"
       << "set cbrange [0:0.25]\nplot '" << path("maps_variance.bin") << "' " << array
       << " with image notitle\n";
  }
  gp << "unset multiplot\n";
  gp.close();
  if (!gp) return Status::IoError(path("figures.gp") + ": cannot write");

  if (std::system("command -v gnuplot > /dev/null 2>&1") != 0) {
    *note = "gnuplot not installed: wrote " + path("figures.gp") + " but no PNGs";
    return Status::Ok();
  }
  const std::string cmd = "gnuplot '" + path("figures.gp") + "'";
  if (std::system(cmd.c_str()) != 0)
    return Status::IoError("gnuplot failed on " + path("figures.gp"));
  return Status::Ok();
}

}  // namespace bgkmap::cli
