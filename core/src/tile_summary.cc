#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

TileSummary SummarizeTile(const GridGeometry& geometry, TileKey key, const Tile* tile) {
  TileSummary s;
  if (tile == nullptr) return s;
  const Tile::KnownCells known = tile->Known();
  const CellBox& local = known.local_box;
  if (local.empty()) return s;
  s.known_cells = static_cast<uint32_t>(known.count);
  s.known_box = geometry.LocalToMap(key, local);
  return s;
}

}  // namespace bgkmap
