// Bands of whole tiles, and where to cut a map into them so that parallel integrations, one per
// band, take about the same time (`bgkmap build --threads N` across a drive, the server within
// one dense scan: scan_bands.h).
//
// A band integrates every observed cell within its halo (ScanReachCells), so its work is the
// cells in the band grown by the halo on both sides, and the slowest band sets the wall time. The
// cut is at tile borders (a band holds whole tiles) and minimises the largest band's work: a
// border through a dense stretch costs its halo twice, a border rounded to the wrong tile leaves
// one band late.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

// The tiles whose first cell along one axis lies in [lo, hi): the whole map by default.
struct TileBand {
  bool along_x = true;
  int64_t lo = std::numeric_limits<int>::min();
  int64_t hi = int64_t{std::numeric_limits<int>::max()} + 1;

  bool IsWholeMap() const { return lo == TileBand{}.lo && hi == TileBand{}.hi; }
  bool Owns(TileKey key, int tile_size) const {
    const int64_t first = int64_t{along_x ? key.x : key.y} * tile_size;
    return first >= lo && first < hi;
  }
  // The band grown by `halo` cells along its axis, the whole map across it.
  CellBox Reach(int halo) const;
};

// `cells[i]`: the observed cells (summed over scans) whose coordinate along the cut axis is
// `first + i`. Returns the borders, increasing multiples of `tile_size` strictly inside
// (first, first + cells.size()), that cut the axis into at most `bands` bands (borders.size() + 1)
// whose largest work is the least possible; among equal cuts, the one with the fewest bands.
// A band [lo, hi) works on the cells with lo - halo <= coordinate < hi + halo.
std::vector<int64_t> CutBorders(const std::vector<int64_t>& cells, int64_t first, int tile_size,
                                int halo, int bands);

// The bands of the cut: [-inf, b0), [b0, b1), ..., [bn, +inf) along the given axis.
std::vector<TileBand> BandsBetween(const std::vector<int64_t>& borders, bool along_x);

}  // namespace bgkmap
