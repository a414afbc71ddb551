#include "bgkmap/eval/change_score.h"

#include <cmath>

namespace bgkmap::eval {

double ChangeCounts::rate() const {
  return judged > 0 ? static_cast<double>(wrong) / static_cast<double>(judged) : std::nan("");
}

bool IsJudged(const ChangedCell& c, ChangeKind kind) {
  if (kind == ChangeKind::kAppeared) {
    return c.before == CellState::kTraversable && c.after == CellState::kNonTraversable;
  }
  const bool cleared = c.before == CellState::kNonTraversable && c.after == CellState::kTraversable;
  return cleared || c.moved;
}

ChangeCounts ScoreChange(const TerrainMap& map, std::span<const ChangedCell> cells,
                         ChangeKind kind) {
  ChangeCounts n;
  for (const ChangedCell& c : cells) {
    ++n.judged;
    const CellEstimate e = map.Estimate(c.cell);
    if (e.state == CellState::kUnknown) {
      ++n.unknown;
      if (kind == ChangeKind::kAppeared) ++n.wrong;
      continue;
    }
    if (kind == ChangeKind::kAppeared) {
      n.wrong += e.state != CellState::kNonTraversable;
      continue;
    }
    const bool still_blocked = c.before == CellState::kNonTraversable &&
                               c.after == CellState::kTraversable &&
                               e.state == CellState::kNonTraversable;
    const double to_old = std::abs(static_cast<double>(e.elevation) - c.z_before);
    const double to_new = std::abs(static_cast<double>(e.elevation) - c.z_after);
    // A cell judged for its elevation: the map's is nearer the old than the new truth.
    const bool still_high = c.moved && std::isfinite(e.elevation) && to_old < to_new;
    n.wrong += still_blocked || still_high;
  }
  return n;
}

}  // namespace bgkmap::eval
