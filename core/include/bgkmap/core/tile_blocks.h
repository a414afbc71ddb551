// A tile's cells in 16 x 16 blocks: the grain at which integration reports what it changed, so
// a region delta sends a tile's changed blocks instead of the whole tile (docs/server.md, "Region
// deltas"). Blocks exist where the tile size is a power of two of at least 16 (a 64-cell tile
// has blocks of 4 x 4 cells): bit bx of row by of a mask is the block at (bx, by), tile_size / 16
// cells square, bx along x. Elsewhere every mask is TileBlocks::All().
#pragma once

#include <array>
#include <bit>
#include <cstdint>

#include "bgkmap/core/grid.h"

namespace bgkmap {

inline constexpr int kTileBlocksPerSide = 16;

// A set of a tile's blocks: 16 rows of 16 bits, four rows to a word.
class TileBlocks {
 public:
  static constexpr int kRowsPerWord = 64 / kTileBlocksPerSide;
  static constexpr int kWords = kTileBlocksPerSide / kRowsPerWord;

  constexpr TileBlocks() = default;
  static constexpr TileBlocks All() {
    TileBlocks b;
    for (uint64_t& w : b.w_) w = ~uint64_t{0};
    return b;
  }

  // The blocks of row `by`, bit bx for block (bx, by).
  constexpr unsigned Row(int by) const {
    return static_cast<unsigned>(w_[by / kRowsPerWord] >>
                                 (by % kRowsPerWord * kTileBlocksPerSide)) &
           0xffffu;
  }
  // Adds blocks [bx0, bx1] x [by0, by1].
  constexpr void AddRect(int bx0, int by0, int bx1, int by1) {
    const uint64_t row = ((uint64_t{2} << (bx1 - bx0)) - 1) << bx0;
    for (int by = by0; by <= by1; ++by) {
      w_[by / kRowsPerWord] |= row << (by % kRowsPerWord * kTileBlocksPerSide);
    }
  }
  constexpr bool Contains(const TileBlocks& o) const {
    for (int i = 0; i < kWords; ++i) {
      if ((w_[i] & o.w_[i]) != o.w_[i]) return false;
    }
    return true;
  }
  constexpr bool Empty() const { return *this == TileBlocks(); }
  constexpr bool IsAll() const { return *this == All(); }
  constexpr int Count() const {
    int n = 0;
    for (uint64_t w : w_) n += std::popcount(w);
    return n;
  }
  constexpr TileBlocks& operator|=(const TileBlocks& o) {
    for (int i = 0; i < kWords; ++i) w_[i] |= o.w_[i];
    return *this;
  }
  friend constexpr TileBlocks operator|(TileBlocks a, const TileBlocks& b) { return a |= b; }
  friend constexpr bool operator==(const TileBlocks&, const TileBlocks&) = default;

 private:
  std::array<uint64_t, kWords> w_ = {};
};

// A tile and the blocks of it that changed (All(): the whole tile).
struct ChangedTile {
  TileKey key;
  TileBlocks blocks = TileBlocks::All();
  friend bool operator==(const ChangedTile&, const ChangedTile&) = default;
};

// log2 of a block's side in cells, or -1 where `tile_size` has no blocks.
constexpr int TileBlockShift(int tile_size) {
  return tile_size >= kTileBlocksPerSide && std::has_single_bit(static_cast<unsigned>(tile_size))
             ? std::countr_zero(static_cast<unsigned>(tile_size)) -
                   std::countr_zero(static_cast<unsigned>(kTileBlocksPerSide))
             : -1;
}

// Adds to `blocks` those meeting the tile-local box [x0, x1] x [y0, y1] (inside the tile,
// non-empty); all of them where `shift` is -1.
constexpr void AddTileBlocksOf(TileBlocks& blocks, int shift, int x0, int y0, int x1, int y1) {
  if (shift < 0) {
    blocks = TileBlocks::All();
  } else {
    blocks.AddRect(x0 >> shift, y0 >> shift, x1 >> shift, y1 >> shift);
  }
}

// The blocks meeting the tile-local box [x0, x1] x [y0, y1] (AddTileBlocksOf's).
constexpr TileBlocks TileBlocksOf(int shift, int x0, int y0, int x1, int y1) {
  TileBlocks out;
  AddTileBlocksOf(out, shift, x0, y0, x1, y1);
  return out;
}

// The map cells of blocks [bx0, bx1] x [by0, by1] of tile `key` (the geometry's tile size must
// have blocks).
inline CellBox TileBlockCells(const GridGeometry& g, TileKey key, int bx0, int by0, int bx1,
                              int by1) {
  const int side = g.tile_size() / kTileBlocksPerSide;
  const CellIndex o = g.TileOrigin(key);
  return {{o.x + bx0 * side, o.y + by0 * side},
          {o.x + (bx1 + 1) * side - 1, o.y + (by1 + 1) * side - 1}};
}

}  // namespace bgkmap
