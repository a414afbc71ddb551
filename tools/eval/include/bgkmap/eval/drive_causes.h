// Why driven cells come out blocked or unknown: each driven cell's history, scan by scan, read
// from the map's statistics before and after every scan (docs/results.md, "Real drives: today's
// map"). The final statistics say which condition of the state rule fails (eval/drive_score.h);
// the history says what made it fail: free-space evidence cutting the cell or zeroing its Beta
// counts, a vehicle standing there when the evidence was learnt, too few observations.
//
// Events, per cell and scan k (statistics after scan k against after scan k - 1):
//   cut:    W fell below half (free-space evidence scaled the cell by clear_decay; no other rule
//           lowers W by half: the caps scale a cell down to the cap, never below);
//   reset:  A + B fell below half (zeroed because a cell within l was contradicted, or cut);
//   gain:   A or B grew; the scan adding the most A is the cell's main obstacle evidence, kept
//           with whether a vehicle was near the cell then (traffic: within the reach of its
//           evidence, TrafficJudge::Near) and the cell's range from the sensor.
//
// Causes, one per judged cell, the first that applies:
//   traversable;
//   unknown, never seen (no weight ever) / unknown, forgotten (cut to nothing);
//   no value (weight, no traversability evidence);
//   high mean, its main obstacle evidence learnt while a vehicle was near (simulated traffic);
//   high mean, the surface around it has a step, slope or roughness over the criteria now;
//   high mean, history (the surface is fine now: learnt from an earlier one);
//   disagreement (sqrt(D) > step_crit, the mean fine);
//   variance only, within `recent_scans` of a cut or reset (the evidence was thrown away);
//   variance only, little evidence (never enough observations).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/drive_score.h"

namespace bgkmap::eval {

enum class Cause : uint8_t {
  kTraversable,
  kUnknownNeverSeen,
  kUnknownForgotten,
  kNoValue,
  kMeanVehicle,
  kMeanSurfaceNow,
  kMeanHistory,
  kDisagreement,
  kVarianceAfterReset,
  kVarianceSparse,
};
inline constexpr int kCauseCount = 10;
std::string_view CauseName(Cause c);

struct CauseCounts {
  std::array<int64_t, kCauseCount> n{};
  int64_t judged = 0;
  int64_t cells_cut = 0, cells_reset = 0;  // judged cells cut / reset at least once before
  double mean_range_sum = 0;               // high-mean cells: range of their main evidence
  int64_t mean_range_cells = 0;
  int64_t& operator[](Cause c) { return n[static_cast<size_t>(c)]; }
  int64_t operator[](Cause c) const { return n[static_cast<size_t>(c)]; }
  double mean_evidence_range() const;  // metres; NaN without high-mean cells
};

class DriveCauses {
 public:
  // `occupied(k, cell)`: whether a vehicle was near the cell at scan k (null: no traffic known).
  DriveCauses(std::span<const DrivenCell> driven, std::function<bool(int, CellIndex)> occupied = {},
              int recent_scans = 5);

  // After scan k (poses[k] its sensor pose), in order: records the events, then judges the cells
  // scan k + 1 arrives at (on the map before that scan).
  void AfterScan(int k, const Pose& pose, const TerrainMap& map);
  // Judges every driven cell on the final map.
  void Finish(const TerrainMap& map);

  const CauseCounts& on_arrival() const { return on_arrival_; }
  const CauseCounts& final() const { return final_; }
  // The cause of driven cell i (in `driven` order) on the final map (after Finish).
  Cause final_cause(size_t i) const { return final_causes_[i]; }

 private:
  struct History {
    double w = 0, a = 0, ab = 0;  // after the last scan
    bool seen = false;
    int last_cut = -1000, last_reset = -1000;
    int cuts = 0, resets = 0;
    double max_da = 0;
    bool max_da_vehicle = false;
    double max_da_range = 0;
  };
  Cause Judge(size_t i, int k, const TerrainMap& map) const;
  void Count(size_t i, int k, const TerrainMap& map, CauseCounts& into, Cause* cause = nullptr);

  std::vector<DrivenCell> driven_;
  std::vector<std::vector<size_t>> arrivals_;  // [k]: driven cells scan k arrives at
  std::function<bool(int, CellIndex)> occupied_;
  int recent_;
  std::vector<History> history_;
  CauseCounts on_arrival_, final_;
  std::vector<Cause> final_causes_;
  int last_scan_ = -1;
};

}  // namespace bgkmap::eval
