// Counts and bounds of the whole served map, kept incrementally: every change hands in the new
// summaries of the tiles it touched (one update per change, so a reader sees whole changes), and
// Info and /metrics read totals without locking or walking the map.
#pragma once

#include <cstdint>
#include <mutex>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

struct MapSummary {
  uint64_t tile_count = 0;  // tiles with a known cell
  uint64_t known_cells = 0;
  CellBox known_bounds;  // empty when nothing is known
};

class MapSummaryIndex {
 public:
  // Sets the summaries of `keys` (same order) as one step.
  void Update(std::span<const TileKey> keys, std::span<const TileSummary> summaries);
  MapSummary Get() const;

 private:
  // Requires mu_. The union of every tile's box: after a tile shrank or went.
  void RecomputeBounds();

  mutable std::mutex mu_;
  std::unordered_map<TileKey, TileSummary, TileKeyHash> tiles_;  // known tiles only
  uint64_t known_cells_ = 0;
  CellBox bounds_;
};

}  // namespace bgkmap
