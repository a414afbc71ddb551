// Damaging a stored tile the way a disk error would, for the corruption tests of the server.
#pragma once

#include <string>

#include "bgkmap/core/grid.h"

namespace bgkmap::testing {

enum class StoredTilePick { kFirst, kMiddle };  // in the store's key order

// Compacts the (closed) store in `dir` so that its tiles are in SST files, as after a while in
// service, then flips one byte in the middle of the chosen tile's stored value with RocksDB
// directly. Returns the tile's key. Reports a test failure if the store has no tile.
TileKey CorruptStoredTile(const std::string& dir, StoredTilePick pick = StoredTilePick::kFirst);

}  // namespace bgkmap::testing
