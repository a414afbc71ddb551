// Rebuilding the served map from a store: the tiles of the last checkpoint, then the log
// records after it replayed in version order.
//
// Replay is exact: a record holds the prepared scan's training set bit for bit, and integrating
// a prepared scan into the same tiles at the same version is deterministic. Because each scan's
// traversability is computed from the elevation the map had at that moment, records are
// replayed strictly in version order, each onto the state all lower versions produced.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/tile_store.h"

namespace bgkmap::storage {

struct RecoveryReport {
  uint64_t checkpoint_version = 0;
  uint64_t map_version = 0;  // of the recovered map (= store.map_version())
  uint64_t scans_replayed = 0;
  uint64_t clears_replayed = 0;
  uint64_t corrections_replayed = 0;  // rebuilt from their base (reintegration.h)
  uint64_t tiles_loaded = 0;
  // Log records that failed their checksum: their changes are lost (and later scans were
  // replayed without them). Empty in a healthy store.
  std::vector<uint64_t> corrupt_records;
  // Tiles that could not be loaded: replay continued as if they were empty, so the map holds
  // wrong statistics for them until they are rebuilt; store.CorruptTiles() lists them too.
  std::vector<TileKey> corrupt_tiles;
  // Tiles the replayed records changed, sorted: a scan's write tiles, and for a clear the stored
  // tiles in its box. The map holds them newer than the store does.
  std::vector<TileKey> touched_tiles;
  double seconds = 0;

  bool clean() const { return corrupt_records.empty() && corrupt_tiles.empty(); }
};

// Brings `map` to the store's latest state: loads the stored tiles that the log records after
// the checkpoint touch (their write and read tiles; for a clear, the stored tiles in its box),
// replays the records in version order and sets map.version() to store.map_version().
// Tiles the log does not touch are not read: they are current in the store, for LoadTileInto()
// on demand (or LoadAllTiles()).
// Precondition: `map` was created with store.params() and holds no tiles.
// Returns an error only if the log cannot be read at all; damage is reported, not fatal.
Result<RecoveryReport> RecoverMap(const TileStore& store, TerrainMap& map);

// Sets the tiles at `keys` in `map` to `tiles`, as changed at `version` (a correction's); a null
// tile becomes an empty one (so that an older stored copy is never loaded in its place).
void InstallTiles(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles,
                  uint64_t version, TerrainMap& map);

// Copies the stored tile at `key` into `map`, replacing what the map holds there. Returns
// false if the store has no such tile; the store's DataLoss or IoError otherwise.
Result<bool> LoadTileInto(const TileStore& store, TileKey key, TerrainMap& map);

// Loads every stored tile that `map` does not hold yet (the ones it holds are newer: recovered
// or changed since). Corrupt tiles are skipped and appended to `corrupt` (if not null).
Status LoadAllTiles(const TileStore& store, TerrainMap& map,
                    std::vector<TileKey>* corrupt = nullptr);

}  // namespace bgkmap::storage
