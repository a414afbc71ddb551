// How well a map follows a change of the world (docs/results.md, "Changing worlds"): an object
// that disappeared or appeared, judged on the cells it changed.
//
// The judged cells of an object are those within robot_radius of its footprint (the cells whose
// true state it can decide) that the change really changed, between the true world just before
// the change and just after it:
//   removed: cells that were non-traversable and are traversable now, or whose true elevation
//            moved by more than half the object's height;
//   appeared: cells that were traversable and are non-traversable now.
// Only cells a ground-truth scan set sees are judged (the world with the removed object, the
// world with the appeared one), as for coverage and AUC.
//
// A judged cell of a removed object is **stale** if the map knows it and still shows the object:
// non-traversable where the truth turned traversable, or an elevation nearer the old than the
// new true elevation where that moved. A judged cell of an appeared object is **missed** if the
// map does not call it non-traversable (traversable or unknown).
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap::eval {

enum class ChangeKind { kRemoved, kAppeared };

// The truth of one judged cell before and after the change.
struct ChangedCell {
  CellIndex cell;
  float z_before = 0, z_after = 0;
  CellState before = CellState::kUnknown, after = CellState::kUnknown;
  bool moved = false;  // the true elevation moved by more than half the object's height
};

// `before` and `after` are ground truths (kElevation, kState; NaN = not judged) over the same
// cells: the object's surroundings in the world just before and just after the change.
// `visible(cell)` says whether a ground-truth scan set sees the cell.
template <typename Visible>
std::vector<ChangedCell> JudgedCells(const Raster& before, const Raster& after, ChangeKind kind,
                                     double height, Visible&& visible);

struct ChangeCounts {
  int64_t judged = 0;
  int64_t wrong = 0;    // stale (removed) or missed (appeared)
  int64_t unknown = 0;  // judged cells the map does not know (missed, if appeared)
  double rate() const;  // wrong / judged; NaN without judged cells
  ChangeCounts& operator+=(const ChangeCounts& o) {
    judged += o.judged;
    wrong += o.wrong;
    unknown += o.unknown;
    return *this;
  }
};

ChangeCounts ScoreChange(const TerrainMap& map, std::span<const ChangedCell> cells,
                         ChangeKind kind);

// Whether a cell's truth changed enough to be judged (see above; `moved` set).
bool IsJudged(const ChangedCell& c, ChangeKind kind);

template <typename Visible>
std::vector<ChangedCell> JudgedCells(const Raster& before, const Raster& after, ChangeKind kind,
                                     double height, Visible&& visible) {
  std::vector<ChangedCell> out;
  const std::vector<float>*zb = before.Find(Layer::kElevation), *sb = before.Find(Layer::kState);
  const std::vector<float>*za = after.Find(Layer::kElevation), *sa = after.Find(Layer::kState);
  if (!zb || !sb || !za || !sa || before.box != after.box) return out;
  for (int64_t row = 0; row < before.rows; ++row) {
    for (int64_t col = 0; col < before.cols; ++col) {
      const size_t k = static_cast<size_t>(row * before.cols + col);
      if ((*sb)[k] != (*sb)[k] || (*sa)[k] != (*sa)[k]) continue;  // NaN: not in the region
      ChangedCell c;
      c.cell = {before.box.min.x + static_cast<int>(col), before.box.max.y - static_cast<int>(row)};
      c.z_before = (*zb)[k];
      c.z_after = (*za)[k];
      c.before = static_cast<CellState>(static_cast<int>((*sb)[k]));
      c.after = static_cast<CellState>(static_cast<int>((*sa)[k]));
      c.moved = std::abs(static_cast<double>(c.z_before) - c.z_after) > 0.5 * height;
      if (IsJudged(c, kind) && visible(c.cell)) out.push_back(c);
    }
  }
  return out;
}

}  // namespace bgkmap::eval
