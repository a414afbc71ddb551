// A tile's cells in 8 x 8 blocks: the grain at which integration reports what it changed, so a
// region delta sends a tile's changed blocks instead of the whole tile (docs/server.md, "Region
// deltas"). Blocks exist where the tile size is a power of two of at least 8: bit by * 8 + bx of
// a mask is the block at (bx, by), tile_size / 8 cells square, bx along x. Elsewhere every mask
// is kAllTileBlocks.
#pragma once

#include <bit>
#include <cstdint>

#include "bgkmap/core/grid.h"

namespace bgkmap {

inline constexpr int kTileBlocksPerSide = 8;
inline constexpr uint64_t kAllTileBlocks = ~uint64_t{0};

// A tile and the blocks of it that changed (kAllTileBlocks: the whole tile).
struct ChangedTile {
  TileKey key;
  uint64_t blocks = kAllTileBlocks;
  friend bool operator==(const ChangedTile&, const ChangedTile&) = default;
};

// log2 of a block's side in cells, or -1 where `tile_size` has no blocks.
constexpr int TileBlockShift(int tile_size) {
  return tile_size >= kTileBlocksPerSide && std::has_single_bit(static_cast<unsigned>(tile_size))
             ? std::countr_zero(static_cast<unsigned>(tile_size)) - 3
             : -1;
}

// The blocks meeting the tile-local box [x0, x1] x [y0, y1] (inside the tile, non-empty);
// kAllTileBlocks where `shift` is -1.
inline uint64_t TileBlocksOf(int shift, int x0, int y0, int x1, int y1) {
  if (shift < 0) return kAllTileBlocks;
  const int bx0 = x0 >> shift, bx1 = x1 >> shift;
  const uint64_t row = ((uint64_t{2} << (bx1 - bx0)) - 1) << bx0;
  uint64_t mask = 0;
  for (int by = y0 >> shift; by <= (y1 >> shift); ++by) mask |= row << (by * kTileBlocksPerSide);
  return mask;
}

// The map cells of blocks [bx0, bx1] of block row `by` of tile `key` (the geometry's tile size
// must have blocks).
inline CellBox TileBlockRowCells(const GridGeometry& g, TileKey key, int by, int bx0, int bx1) {
  const int side = g.tile_size() / kTileBlocksPerSide;
  const CellIndex o = g.TileOrigin(key);
  return {{o.x + bx0 * side, o.y + by * side},
          {o.x + (bx1 + 1) * side - 1, o.y + (by + 1) * side - 1}};
}

}  // namespace bgkmap
