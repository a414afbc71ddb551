// Where `bgkmap build --threads N` cuts the map into bands, one per thread (parallel_mapping.h).
//
// A band integrates every observed cell within its halo, so its work is the cells in the band
// grown by the halo on both sides, and the slowest band sets the wall time. The cut is at tile
// borders (a band holds whole tiles) and minimises the largest band's work: a border through a
// dense stretch costs its halo twice, a border rounded to the wrong tile leaves one band late.
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap::cli {

// `cells[i]`: the observed cells (summed over scans) whose coordinate along the cut axis is
// `first + i`. Returns the borders, increasing multiples of `tile_size` strictly inside
// (first, first + cells.size()), that cut the axis into at most `bands` bands (borders.size() + 1)
// whose largest work is the least possible; among equal cuts, the one with the fewest bands.
// A band [lo, hi) works on the cells with lo - halo <= coordinate < hi + halo.
std::vector<int64_t> CutBorders(const std::vector<int64_t>& cells, int64_t first, int tile_size,
                                int halo, int bands);

}  // namespace bgkmap::cli
