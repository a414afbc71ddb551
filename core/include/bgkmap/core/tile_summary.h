// What a map's overview needs of one tile without its cells: how many cells are known and where.
// The served map keeps these per tile, for tiles in memory and tiles only in the store alike, so
// counts and bounds are answered without reading (or locking) any tile.
#pragma once

#include <cstdint>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile.h"

namespace bgkmap {

struct TileSummary {
  uint32_t known_cells = 0;
  CellBox known_box;  // map cells; empty when no cell is known

  bool operator==(const TileSummary&) const = default;
};

// The summary of the tile at `key` (null: no tile, an empty summary).
TileSummary SummarizeTile(const GridGeometry& geometry, TileKey key, const Tile* tile);

}  // namespace bgkmap
