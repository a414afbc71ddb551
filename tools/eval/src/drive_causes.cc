#include "bgkmap/eval/drive_causes.h"

#include <cmath>

namespace bgkmap::eval {

std::string_view CauseName(Cause c) {
  switch (c) {
    case Cause::kTraversable:
      return "traversable";
    case Cause::kUnknownNeverSeen:
      return "unknown_never_seen";
    case Cause::kUnknownForgotten:
      return "unknown_forgotten";
    case Cause::kNoValue:
      return "no_value";
    case Cause::kMeanVehicle:
      return "mean_learnt_from_vehicle";
    case Cause::kMeanSurfaceNow:
      return "mean_surface_now";
    case Cause::kMeanHistory:
      return "mean_history";
    case Cause::kDisagreement:
      return "disagreement";
    case Cause::kVarianceAfterReset:
      return "variance_after_cut_or_reset";
    case Cause::kVarianceSparse:
      return "variance_little_evidence";
  }
  return "?";
}

double CauseCounts::mean_evidence_range() const {
  return mean_range_cells ? mean_range_sum / static_cast<double>(mean_range_cells) : NAN;
}

DriveCauses::DriveCauses(std::span<const DrivenCell> driven,
                         std::function<bool(int, CellIndex)> occupied, int recent_scans)
    : driven_(driven.begin(), driven.end()),
      occupied_(std::move(occupied)),
      recent_(recent_scans),
      history_(driven.size()),
      final_causes_(driven.size(), Cause::kTraversable) {
  for (size_t i = 0; i < driven_.size(); ++i) {
    const size_t k = static_cast<size_t>(std::max(driven_[i].first_scan, 0));
    if (arrivals_.size() <= k) arrivals_.resize(k + 1);
    arrivals_[k].push_back(i);
  }
}

void DriveCauses::AfterScan(int k, const Pose& pose, const TerrainMap& map) {
  const GridGeometry& g = map.geometry();
  for (size_t i = 0; i < driven_.size(); ++i) {
    const CellIndex c = driven_[i].cell;
    const Tile* t = map.FindTile(g.TileOf(c));
    const int j = g.LocalIndex(c);
    const double w = t ? t->w()[j] : 0.0;
    const double a = t ? t->a()[j] : 0.0, b = t ? t->b()[j] : 0.0;
    History& h = history_[i];
    if (h.w > 0 && w < 0.5 * h.w) {
      h.last_cut = k;
      ++h.cuts;
    }
    double da = a - h.a;  // the obstacle evidence this scan added
    if (h.ab > 0 && a + b < 0.5 * h.ab) {
      h.last_reset = k;
      ++h.resets;
      da = a;  // what is left after the reset came from this scan
    }
    if (da > h.max_da) {
      h.max_da = da;
      h.max_da_vehicle = occupied_ && occupied_(k, c);
      h.max_da_range = std::hypot(g.CellCenterX(c.x) - pose.translation.x(),
                                  g.CellCenterY(c.y) - pose.translation.y());
    }
    h.w = w;
    h.a = a;
    h.ab = a + b;
    h.seen |= w > 0;
  }
  last_scan_ = k;
  if (static_cast<size_t>(k + 1) < arrivals_.size()) {
    for (size_t i : arrivals_[k + 1]) Count(i, k, map, on_arrival_);
  }
}

void DriveCauses::Finish(const TerrainMap& map) {
  for (size_t i = 0; i < driven_.size(); ++i) Count(i, last_scan_, map, final_, &final_causes_[i]);
}

Cause DriveCauses::Judge(size_t i, int k, const TerrainMap& map) const {
  const History& h = history_[i];
  const CellIndex c = driven_[i].cell;
  const CellState state = map.Estimate(c).state;
  if (state == CellState::kTraversable) return Cause::kTraversable;
  // A cell seen too little (dynamics: unknown with statistics) keeps its reason, no value or the
  // variance; a cell without statistics is unknown.
  const uint8_t r = BlockReasonsAt(map, c);
  if (state == CellState::kUnknown && r == 0)
    return h.seen ? Cause::kUnknownForgotten : Cause::kUnknownNeverSeen;
  if (r & kNoValue) return Cause::kNoValue;
  if (r & kHighMean) {
    if (h.max_da_vehicle) return Cause::kMeanVehicle;
    SurfaceCheck s;
    if (CheckSurface(map, c, &s) && (s.step || s.slope || s.roughness))
      return Cause::kMeanSurfaceNow;
    return Cause::kMeanHistory;
  }
  if (r & kDisagreement) return Cause::kDisagreement;
  const int last = std::max(h.last_cut, h.last_reset);
  return k - last < recent_ ? Cause::kVarianceAfterReset : Cause::kVarianceSparse;
}

void DriveCauses::Count(size_t i, int k, const TerrainMap& map, CauseCounts& into, Cause* cause) {
  const Cause c = Judge(i, k, map);
  if (cause != nullptr) *cause = c;
  ++into.judged;
  ++into[c];
  const History& h = history_[i];
  into.cells_cut += h.cuts > 0;
  into.cells_reset += h.resets > 0;
  if (c == Cause::kMeanVehicle || c == Cause::kMeanSurfaceNow || c == Cause::kMeanHistory) {
    into.mean_range_sum += h.max_da_range;
    ++into.mean_range_cells;
  }
}

}  // namespace bgkmap::eval
