// A consistent, read-only view of a TileStore's tiles as of one moment (a RocksDB snapshot).
//
// A server exports a map while it keeps ingesting: at a barrier it checkpoints the map at
// version V, takes a snapshot, releases the barrier and reads the tiles from the snapshot. Later
// checkpoints change the store, not what the snapshot lists or loads.
//
// Made by TileStore::NewSnapshot(). Thread-safe like the store. Must be destroyed before the
// store; while one is open the store cannot reopen its database in Resume().
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/storage/tile_store.h"

namespace bgkmap::storage {

class TileSnapshot {
 public:
  ~TileSnapshot();  // releases the RocksDB snapshot
  TileSnapshot(const TileSnapshot&) = delete;
  TileSnapshot& operator=(const TileSnapshot&) = delete;

  // The store's checkpoint version when the snapshot was taken: its tiles are the map after
  // exactly the changes up to it.
  uint64_t checkpoint_version() const { return checkpoint_version_; }

  // Like TileStore::ListTiles, as of the snapshot.
  Result<std::vector<StoredTileInfo>> ListTiles() const;
  Result<std::vector<StoredTileInfo>> ListTiles(TileKey min, TileKey max) const;

  // Like TileStore::LoadTile, as of the snapshot: null if there was no tile at `key`; DataLoss
  // naming the tile if it fails its checksum (not added to the store's CorruptTiles(): the
  // store may have rewritten it since); IoError on a read failure.
  Result<std::unique_ptr<Tile>> LoadTile(TileKey key) const;

 private:
  friend class TileStore;
  TileSnapshot(const TileStore& store, const rocksdb::Snapshot* snapshot,
               uint64_t checkpoint_version);

  const TileStore& store_;
  const rocksdb::Snapshot* snapshot_;
  uint64_t checkpoint_version_;
};

}  // namespace bgkmap::storage
