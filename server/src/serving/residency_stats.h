// Which tiles of a map on a store are in memory (serving/tile_residency.h), for Info and /metrics.
#pragma once

#include <cstdint>

namespace bgkmap {

struct ResidencyStats {
  uint64_t resident_tiles = 0;
  uint64_t resident_bytes = 0;  // tile memory, each tile in its form (TileTable::ResidentBytes)
  uint64_t packed_tiles = 0;    // of the resident ones (tile.h)
  uint64_t tiles_loaded = 0;    // from the store, since start
  uint64_t tiles_evicted = 0;   // since start
  uint64_t tiles_packed = 0;    // since start (a tile packed again after a use counts again)
};

}  // namespace bgkmap
