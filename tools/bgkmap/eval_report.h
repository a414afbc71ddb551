// What `bgkmap eval` measured for one method, and the files it writes from that: JSON, a
// Markdown table in the layout of the paper's Table 1, and gnuplot figures (ROC curves as in
// Fig. 5, maps side by side as in Fig. 3).
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/eval/change_score.h"
#include "bgkmap/eval/drive_causes.h"
#include "bgkmap/eval/drive_score.h"
#include "bgkmap/eval/map_score.h"
#include "bgkmap/eval/traffic_score.h"

namespace bgkmap::cli {

// With --align-z: what the vertical alignment of each scan to the map before it did (offline
// pass; core/vertical_alignment.h).
struct AlignmentStats {
  size_t aligned = 0, too_few_cells = 0, beyond_bound = 0;
  double sum_abs_dz = 0, max_abs_dz = 0;      // m, over the aligned scans
  size_t levelled = 0;                        // aligned scans whose tilt was levelled too
  double sum_tilt_deg = 0, max_tilt_deg = 0;  // over the levelled scans
  double seconds = 0;                         // preparing and comparing, outside the stage times
};

struct MethodResult {
  Method method = Method::kBgkPlus;
  size_t scans = 0;
  size_t skipped = 0;  // at the scan rate, by the two-process gate
  // Mean seconds per scan over all scans (offline pass): the paper's three stages, plus the
  // preparation (filtering, transform, binning) that the paper counts as registration.
  double prepare_s = 0, elevation_s = 0, features_s = 0, traversability_s = 0;
  double max_scan_s = 0;
  eval::MapScore realtime;  // map built from the admitted scans only
  eval::MapScore offline;   // map built from every scan
  Raster maps;              // realtime map over the truth box: kState, kTraversabilityVariance
  // With a changes.json: the map of every scan up to `scans_after` scans past each change
  // (offline pass), pooled over the objects; index j = scans after the change (0: just before).
  std::vector<eval::ChangeCounts> removed;   // stale cells of removed objects
  std::vector<eval::ChangeCounts> appeared;  // missed cells of appeared objects
  // With a footprint (EvalReport::has_drive): the driven cells of the offline map, and the map
  // of the odd scans against the map of the even scans (all cells both know; driven cells).
  eval::DriveScore drive;
  // The same, each driven cell judged once, on the map just before the scan that arrives at it
  // (eval/drive_score.h): what a planner saw of the ground ahead.
  eval::DriveScore drive_on_arrival;
  // Why the blocked and unknown ones are so, from each cell's history (eval/drive_causes.h).
  eval::CauseCounts causes_final, causes_on_arrival;
  eval::MapAgreement odd_even, odd_even_driven;
  eval::TrafficCounts traffic;  // with a traffic.json (EvalReport::has_traffic), offline map
  AlignmentStats alignment;     // with EvalReport::align_z
};

struct EvalReport {
  std::string name;  // dataset name, e.g. "City"
  std::string sequence;
  double rate_hz = 10;
  MapParams params;
  bool has_truth = true;     // scored against a ground truth (coverage, AUC, ...)
  bool has_changes = false;  // a changes.json was scored: eval.json and table.md report it
  bool has_drive = false;    // a footprint was given: driven cells and odd/even agreement
  bool has_odd_even = false;
  bool has_traffic = false;                // a traffic.json was scored
  std::vector<std::string> vehicle_names;  // its vehicles, in TrafficCounts::by_vehicle's order
  int trail_scans = 5, new_scans = 1;
  std::string footprint;  // eval::Footprint::Describe()
  std::string poses;      // the poses the maps were built with, if not the sequence's
  double pose_noise = 0;  // the scale of the pose error added to them (0: none)
  uint32_t pose_noise_seed = 1;
  bool align_z = false;  // each scan aligned vertically to the map before it (--align-z)
  double align_radius_m = 0;
  std::vector<MethodResult> methods;
};

std::string ToJson(const EvalReport& r);
std::string ToMarkdown(const EvalReport& r);

// Writes <dir>/roc.dat, maps_*.bin and the gnuplot scripts, then runs gnuplot (if installed) to
// make <dir>/roc.png and <dir>/maps.png. Returns an error only if a file cannot be written or
// gnuplot fails; a missing gnuplot is reported in `note`.
Status WriteFigures(const EvalReport& r, const Raster& truth, const std::string& dir,
                    std::string* note);

}  // namespace bgkmap::cli
