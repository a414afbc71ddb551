// Sets of cells as per-tile bitmaps, a row of words per cell row, marked a row range at a time:
// the cells within a disk of any of many cells (the union of their disks), each visited once
// afterwards, row by row. Marking a disk is one word operation per row it spans, where walking
// it visits every cell, once per disk it lies in. Internal to core.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap::internal {

class TileRowMarks {
 public:
  // `planes` independent sets over the same cells (e.g. within one disk, within another).
  TileRowMarks(int tile_size, int planes)
      : T_(tile_size),
        shift_(std::has_single_bit(static_cast<unsigned>(tile_size))
                   ? std::countr_zero(static_cast<unsigned>(tile_size))
                   : -1),
        words_per_row_((tile_size + 63) / 64),
        planes_(planes) {}

  // Marks the cells x_from..x_to (inclusive) of row y in set `plane`.
  void MarkRow(int plane, int y, int x_from, int x_to) {
    const int ty = TileOf(y), ly = y - ty * T_;
    for (int x = x_from; x <= x_to;) {
      const int tx = TileOf(x), lx0 = x - tx * T_;
      const int lx1 = std::min(T_ - 1, lx0 + (x_to - x));
      uint64_t* row = RowOf({tx, ty}, plane, ly);
      for (int w = lx0 / 64; w <= lx1 / 64; ++w) {
        const int from = std::max(lx0, w * 64) - w * 64, to = std::min(lx1, w * 64 + 63) - w * 64;
        const uint64_t high = to == 63 ? ~uint64_t{0} : (uint64_t{1} << (to + 1)) - 1;
        row[w] |= high & ~((uint64_t{1} << from) - 1);
      }
      x += lx1 - lx0 + 1;
    }
  }

  // Marks in set `plane` the cells within a disk around any cell of `cells` (sorted by (x, y)):
  // half(d), d = 0..radius, is the disk's half width d rows from its centre (negative: none).
  // A run of the cells in one column reaches, in row y, as far as its nearest cell's disk does.
  template <class Half>
  void MarkDisks(int plane, const std::vector<CellIndex>& cells, int radius, Half&& half) {
    for (size_t a = 0; a < cells.size();) {
      size_t b = a + 1;
      while (b < cells.size() && cells[b].x == cells[a].x && cells[b].y == cells[b - 1].y + 1) ++b;
      const int x = cells[a].x, y0 = cells[a].y, y1 = cells[b - 1].y;
      for (int y = y0 - radius; y <= y1 + radius; ++y) {
        const int h = half(y < y0 ? y0 - y : (y > y1 ? y - y1 : 0));
        if (h >= 0) MarkRow(plane, y, x - h, x + h);
      }
      a = b;
    }
  }

  // Calls fn(key, local_index, cell, in_plane) for every cell of set 0, tile by tile in key
  // order and row by row within a tile; in_plane(p) tells whether set p holds the cell too.
  template <class Fn>
  void ForEachInFirst(Fn&& fn) {
    std::sort(tiles_.begin(), tiles_.end(),
              [](const Marks& a, const Marks& b) { return a.key < b.key; });
    last_ = nullptr;  // the sort moved the tiles
    for (const Marks& m : tiles_) {
      for (int ly = 0; ly < T_; ++ly) {
        for (int w = 0; w < words_per_row_; ++w) {
          for (uint64_t bits = m.words[Offset(0, ly) + w]; bits != 0; bits &= bits - 1) {
            const int lx = w * 64 + std::countr_zero(bits);
            const auto in_plane = [&](int plane) {
              return (m.words[Offset(plane, ly) + lx / 64] >> (lx % 64) & 1) != 0;
            };
            fn(m.key, ly * T_ + lx, CellIndex{m.key.x * T_ + lx, m.key.y * T_ + ly}, in_plane);
          }
        }
      }
    }
  }

 private:
  struct Marks {
    TileKey key;
    std::vector<uint64_t> words;  // plane by plane, row by row
  };

  // FloorDiv(v, T), a shift for the usual power-of-two tiles (an integer division is slow).
  int TileOf(int v) const { return shift_ >= 0 ? v >> shift_ : FloorDiv(v, T_); }

  size_t Offset(int plane, int ly) const {
    return (static_cast<size_t>(plane) * T_ + ly) * words_per_row_;
  }

  uint64_t* RowOf(TileKey key, int plane, int ly) {
    if (last_ == nullptr || !(last_->key == key)) {
      auto it =
          std::find_if(tiles_.begin(), tiles_.end(), [&](const Marks& m) { return m.key == key; });
      if (it == tiles_.end()) {
        tiles_.push_back({key, std::vector<uint64_t>(Offset(planes_, 0), 0)});
        it = tiles_.end() - 1;
      }
      last_ = &*it;
    }
    return last_->words.data() + Offset(plane, ly);
  }

  const int T_;
  const int shift_;  // log2(T) for a power of two, else -1
  const int words_per_row_;
  const int planes_;
  std::vector<Marks> tiles_;
  Marks* last_ = nullptr;  // the tile marked last (a disk's rows mostly fall in one tile)
};

}  // namespace bgkmap::internal
