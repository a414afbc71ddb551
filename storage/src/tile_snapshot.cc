#include "bgkmap/storage/tile_snapshot.h"

#include <climits>

#include "store_db.h"
#include "store_keys.h"

namespace bgkmap::storage {

std::unique_ptr<TileSnapshot> TileStore::NewSnapshot() const {
  const rocksdb::Snapshot* snapshot = db_->db->GetSnapshot();
  // The checkpoint version as of the snapshot, read through it: a checkpoint committing at the
  // same moment is either wholly in the view (tiles and version) or not at all.
  uint64_t version = checkpoint_version();
  rocksdb::ReadOptions read;
  read.snapshot = snapshot;
  std::string value;
  if (db_->db->Get(read, db_->meta, kCheckpointVersionKey, &value).ok()) {
    (void)ParseU64Bytes(value, &version);
  }
  open_snapshots_.fetch_add(1);
  return std::unique_ptr<TileSnapshot>(new TileSnapshot(*this, snapshot, version));
}

TileSnapshot::TileSnapshot(const TileStore& store, const rocksdb::Snapshot* snapshot,
                           uint64_t checkpoint_version)
    : store_(store), snapshot_(snapshot), checkpoint_version_(checkpoint_version) {}

TileSnapshot::~TileSnapshot() {
  store_.db_->db->ReleaseSnapshot(snapshot_);
  store_.open_snapshots_.fetch_sub(1);
}

Result<std::vector<StoredTileInfo>> TileSnapshot::ListTiles() const {
  return ListTiles({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX});
}

Result<std::vector<StoredTileInfo>> TileSnapshot::ListTiles(TileKey min, TileKey max) const {
  return store_.ListTilesAt(min, max, snapshot_);
}

Result<std::unique_ptr<Tile>> TileSnapshot::LoadTile(TileKey key) const {
  return store_.LoadTileAt(key, snapshot_);
}

}  // namespace bgkmap::storage
