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

Json DriveJson(const eval::DriveScore& d) {
  return {{"driven_cells", d.driven},
          {"known_cells", d.known},
          {"traversable_cells", d.traversable},
          {"blocked_cells", d.blocked},
          {"known_share", JsonNumber<Json>(d.known_share())},
          {"traversable_share", JsonNumber<Json>(d.traversable_share())},
          {"blocked_by",
           {{"no_value", d.no_value},
            {"high_mean", d.high_mean},
            {"high_variance", d.high_variance},
            {"disagreement", d.disagreement},
            {"only_high_mean", d.only_mean},
            {"only_high_variance", d.only_variance},
            {"only_disagreement", d.only_disagreement}}},
          {"high_mean_surface_now",
           {{"step", d.mean_step},
            {"slope", d.mean_slope},
            {"roughness", d.mean_roughness},
            {"none", d.mean_flat_now}}},
          {"ground_cells", d.ground_cells},
          {"ground_bias_m", JsonNumber<Json>(d.ground_bias)},
          {"ground_rms_m", JsonNumber<Json>(d.ground_rms)}};
}

Json CausesJson(const eval::CauseCounts& c) {
  Json j;
  j["judged_cells"] = c.judged;
  for (int i = 0; i < eval::kCauseCount; ++i) {
    const auto cause = static_cast<eval::Cause>(i);
    j[std::string(eval::CauseName(cause))] = c[cause];
  }
  j["cells_cut_before"] = c.cells_cut;
  j["cells_reset_before"] = c.cells_reset;
  j["high_mean_evidence_range_m"] = JsonNumber<Json>(c.mean_evidence_range());
  return j;
}

Json VehicleCountsJson(const EvalReport& r, const eval::TrafficCounts& t) {
  Json out = Json::array();
  for (size_t v = 0; v < t.by_vehicle.size(); ++v) {
    const eval::VehicleCounts& c = t.by_vehicle[v];
    out.push_back({{"name", v < r.vehicle_names.size() ? r.vehicle_names[v] : ""},
                   {"trail_judged_cells", c.trail_judged},
                   {"trail_stale_cells", c.trail_stale},
                   {"trail_stale_rate", JsonNumber<Json>(c.stale_rate())},
                   {"new_judged_cells", c.new_judged},
                   {"new_missed_cells", c.new_missed},
                   {"new_missed_rate", JsonNumber<Json>(c.missed_rate())}});
  }
  return out;
}

Json AgreementJson(const eval::MapAgreement& a) {
  return {{"common_cells", a.common},
          {"only_odd", a.only_a},
          {"only_even", a.only_b},
          {"state_agreement", JsonNumber<Json>(a.agreement())},
          {"both_traversable", a.both_traversable},
          {"blocked_in_odd_only", a.a_blocked_only},
          {"blocked_in_even_only", a.b_blocked_only},
          {"blocked_in_one_by",
           {{"no_value", a.split_no_value},
            {"high_mean", a.split_high_mean},
            {"high_variance", a.split_high_variance},
            {"disagreement", a.split_disagreement}}},
          {"dz_mean_m", JsonNumber<Json>(a.dz_mean)},
          {"dz_rms_m", JsonNumber<Json>(a.dz_rms)},
          {"dz_abs_p50_m", JsonNumber<Json>(a.dz_abs_p50)},
          {"dz_abs_p95_m", JsonNumber<Json>(a.dz_abs_p95)},
          {"dz_abs_max_m", JsonNumber<Json>(a.dz_abs_max)}};
}

double Percent(int64_t part, int64_t whole) {
  return whole ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : NAN;
}

// The driven cells' tables: shares, why the blocked ones are blocked, odd against even.
std::string DriveMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "\n| Dataset | Method | Map | Driven cells | Known (%) | Traversable (%) | Blocked | "
       "Ground bias (m) | Ground RMS (m) |\n"
    << "|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    for (const bool arrival : {false, true}) {
      const eval::DriveScore& d = arrival ? m.drive_on_arrival : m.drive;
      o << "| " << r.name << " | " << MethodName(m.method) << " | "
        << (arrival ? "on arrival" : "final") << " | " << d.driven << " | "
        << Cell(100 * d.known_share(), "%.2f") << " | " << Cell(100 * d.traversable_share(), "%.2f")
        << " | " << d.blocked << " | " << Cell(d.ground_bias, "%.3f") << " | "
        << Cell(d.ground_rms, "%.3f") << " |\n";
    }
  }
  o << "\n| Dataset | Method | Map | Blocked | No value | High mean | High variance | Disagreement "
       "| "
       "Mean only | Variance only | Disagreement only | High mean, now: step / slope / rough / "
       "none |\n"
    << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    for (const bool arrival : {false, true}) {
      const eval::DriveScore& d = arrival ? m.drive_on_arrival : m.drive;
      o << "| " << r.name << " | " << MethodName(m.method) << " | "
        << (arrival ? "on arrival" : "final") << " | " << d.blocked << " | " << d.no_value << " | "
        << d.high_mean << " | " << d.high_variance << " | " << d.disagreement << " | "
        << d.only_mean << " | " << d.only_variance << " | " << d.only_disagreement << " | "
        << d.mean_step << " / " << d.mean_slope << " / " << d.mean_roughness << " / "
        << d.mean_flat_now << " |\n";
    }
  }
  o << "\n| Dataset | Method | Map | Judged | Traversable | Unknown: never seen / forgotten | No "
       "value | Mean: vehicle / surface now / history | Disagreement | Variance: after cut or "
       "reset / little evidence | Cut before / reset before | Mean evidence range (m) |\n"
    << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  using eval::Cause;
  for (const MethodResult& m : r.methods) {
    for (const bool arrival : {false, true}) {
      const eval::CauseCounts& c = arrival ? m.causes_on_arrival : m.causes_final;
      o << "| " << r.name << " | " << MethodName(m.method) << " | "
        << (arrival ? "on arrival" : "final") << " | " << c.judged << " | "
        << c[Cause::kTraversable] << " | " << c[Cause::kUnknownNeverSeen] << " / "
        << c[Cause::kUnknownForgotten] << " | " << c[Cause::kNoValue] << " | "
        << c[Cause::kMeanVehicle] << " / " << c[Cause::kMeanSurfaceNow] << " / "
        << c[Cause::kMeanHistory] << " | " << c[Cause::kDisagreement] << " | "
        << c[Cause::kVarianceAfterReset] << " / " << c[Cause::kVarianceSparse] << " | "
        << c.cells_cut << " / " << c.cells_reset << " | " << Cell(c.mean_evidence_range(), "%.1f")
        << " |\n";
    }
  }
  if (!r.has_odd_even) return o.str();
  o << "\n| Dataset | Method | Common cells | State agreement (%) | Blocked in one only (%) | "
       "Its reasons: no value / mean / variance / disagreement | dz RMS (m) | abs dz p50 / p95 "
       "/ max (m) | Driven: common | Driven: agreement (%) |\n"
    << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    const eval::MapAgreement& a = m.odd_even;
    o << "| " << r.name << " | " << MethodName(m.method) << " | " << a.common << " | "
      << Cell(100 * a.agreement(), "%.2f") << " | "
      << Cell(Percent(a.a_blocked_only + a.b_blocked_only, a.common), "%.2f") << " | "
      << a.split_no_value << " / " << a.split_high_mean << " / " << a.split_high_variance << " / "
      << a.split_disagreement << " | " << Cell(a.dz_rms, "%.3f") << " | "
      << Cell(a.dz_abs_p50, "%.3f") << " / " << Cell(a.dz_abs_p95, "%.3f") << " / "
      << Cell(a.dz_abs_max, "%.2f") << " | " << m.odd_even_driven.common << " | "
      << Cell(100 * m.odd_even_driven.agreement(), "%.2f") << " |\n";
  }
  return o.str();
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
                       {"max_scan_s", JsonNumber<Json>(m.max_scan_s)}});
    if (r.has_truth) {
      methods.back()["realtime"] = ScoreJson(m.realtime);
      methods.back()["offline"] = ScoreJson(m.offline);
    }
    if (r.has_changes) methods.back()["change"] = std::move(change);
    if (r.has_traffic) {
      const eval::TrafficCounts& t = m.traffic;
      methods.back()["traffic"] = {{"trail_scans", r.trail_scans},
                                   {"trail_judged_cells", t.trail_judged},
                                   {"trail_stale_cells", t.trail_stale},
                                   {"trail_stale_rate", JsonNumber<Json>(t.stale_rate())},
                                   {"trail_stale_by",
                                    {{"no_value", t.stale_no_value},
                                     {"high_mean", t.stale_mean},
                                     {"high_variance", t.stale_variance},
                                     {"disagreement", t.stale_disagreement}}},
                                   {"new_obstacle_scans", r.new_scans},
                                   {"new_judged_cells", t.new_judged},
                                   {"new_missed_cells", t.new_missed},
                                   {"new_missed_unknown_cells", t.new_unknown},
                                   {"new_missed_rate", JsonNumber<Json>(t.missed_rate())},
                                   {"by_vehicle", VehicleCountsJson(r, t)}};
    }
    if (r.has_drive) {
      methods.back()["drive"] = DriveJson(m.drive);
      methods.back()["drive_on_arrival"] = DriveJson(m.drive_on_arrival);
      methods.back()["causes"] = {{"final", CausesJson(m.causes_final)},
                                  {"on_arrival", CausesJson(m.causes_on_arrival)}};
    }
    if (r.align_z) {
      const AlignmentStats& a = m.alignment;
      const double n = static_cast<double>(a.aligned);
      methods.back()["alignment"] = {
          {"aligned_scans", a.aligned},
          {"too_few_cells_scans", a.too_few_cells},
          {"beyond_bound_scans", a.beyond_bound},
          {"mean_abs_dz_m", JsonNumber<Json>(a.aligned > 0 ? a.sum_abs_dz / n : 0.0)},
          {"max_abs_dz_m", JsonNumber<Json>(a.max_abs_dz)},
          {"levelled_scans", a.levelled},
          {"mean_tilt_deg", JsonNumber<Json>(a.levelled > 0 ? a.sum_tilt_deg / a.levelled : 0.0)},
          {"max_tilt_deg", JsonNumber<Json>(a.max_tilt_deg)},
          {"mean_align_s", JsonNumber<Json>(m.scans > 0 ? a.seconds / m.scans : 0.0)}};
    }
    if (r.has_odd_even) {
      methods.back()["odd_even"] = AgreementJson(m.odd_even);
      methods.back()["odd_even_driven"] = AgreementJson(m.odd_even_driven);
    }
  }
  Json j;
  j["dataset"] = r.name;
  j["sequence"] = r.sequence;
  j["rate_hz"] = JsonNumber<Json>(r.rate_hz);
  j["resolution"] = JsonNumber<Json>(r.params.resolution);
  j["kernel_length"] = JsonNumber<Json>(r.params.kernel_length);
  if (r.has_drive) j["footprint"] = r.footprint;
  if (!r.poses.empty()) j["poses"] = r.poses;
  if (r.pose_noise > 0) {
    j["pose_noise"] = JsonNumber<Json>(r.pose_noise);
    j["pose_noise_seed"] = r.pose_noise_seed;
  }
  if (r.align_z) j["align_z_radius_m"] = JsonNumber<Json>(r.align_radius_m);
  j["methods"] = std::move(methods);
  return JsonText(j);
}

namespace {

// The paper's Table 1 layout, and the changing world's scores per scan.
std::string TruthMarkdown(const EvalReport& r) {
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

// Trails and new obstacles of each vehicle, in traffic.json's order.
std::string TrafficByVehicleMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "\n| Dataset | Method | Vehicle | Trail cells judged | Stale (%) | New-obstacle cells "
       "judged "
       "| Missed (%) |\n|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    for (size_t v = 0; v < m.traffic.by_vehicle.size(); ++v) {
      const eval::VehicleCounts& c = m.traffic.by_vehicle[v];
      o << "| " << r.name << " | " << MethodName(m.method) << " | "
        << (v < r.vehicle_names.size() ? r.vehicle_names[v] : "") << " | " << c.trail_judged
        << " | " << Cell(100 * c.stale_rate(), "%.2f") << " | " << c.new_judged << " | "
        << Cell(100 * c.missed_rate(), "%.2f") << " |\n";
    }
  }
  return o.str();
}

// Trails and new obstacles of the traffic.
std::string TrafficMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "\n| Dataset | Method | Trail cells judged (" << r.trail_scans
    << " scans after) | Stale (%) | Stale cells | Stale by: no value / mean / variance / "
       "disagreement | New-obstacle cells judged ("
    << r.new_scans << " scan after) | Missed (%) | Missed, unknown |\n"
    << "|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodResult& m : r.methods) {
    const eval::TrafficCounts& t = m.traffic;
    o << "| " << r.name << " | " << MethodName(m.method) << " | " << t.trail_judged << " | "
      << Cell(100 * t.stale_rate(), "%.2f") << " | " << t.trail_stale << " | " << t.stale_no_value
      << " / " << t.stale_mean << " / " << t.stale_variance << " / " << t.stale_disagreement
      << " | " << t.new_judged << " | " << Cell(100 * t.missed_rate(), "%.2f") << " | "
      << t.new_unknown << " |\n";
  }
  return o.str();
}

}  // namespace

std::string ToMarkdown(const EvalReport& r) {
  std::ostringstream o;
  if (r.has_truth) o << TruthMarkdown(r);
  if (r.has_traffic) o << TrafficMarkdown(r) << TrafficByVehicleMarkdown(r);
  if (r.has_drive) o << DriveMarkdown(r).substr(r.has_truth ? 0 : 1);  // no leading blank line
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
