// The served map's persistent store (storage/): opens and recovers it at start, journals every
// change to the scan log before it is applied, and writes checkpoints of the changed tiles.
//
// Checkpoints are two steps so that ingestion stalls only for a copy: Capture() runs at a
// scheduler barrier (no change in flight) and copies the tiles changed since the last
// checkpoint; Write() then stores them with TileStore::Checkpoint outside the barrier.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <semaphore>
#include <set>
#include <shared_mutex>
#include <string>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/server/server_config.h"
#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_store.h"
#include "map_store.h"
#include "scan_scheduler.h"
#include "tile_backing.h"

namespace bgkmap {

// Tiles copied at a barrier, ready to be written.
struct CapturedCheckpoint {
  uint64_t version = 0;
  std::vector<TileKey> keys;
  std::vector<std::unique_ptr<Tile>> tiles;  // null: the tile is gone (cleared)
  // Checkpoints are written in the order they were captured: a later one must not land first
  // and drop log records that an earlier, still unwritten one has not stored yet. Held from
  // Capture() to the end of Write() (possibly on another thread, hence a semaphore).
  std::shared_ptr<std::binary_semaphore> order;
};

class MapPersistence final : public ChangeJournal, public TileBacking {
 public:
  // Opens (or creates) the store in config.data_dir and brings `map` (empty, created with
  // `params`) to the store's latest state: the tiles the log after the last checkpoint touches
  // are replayed into it and checkpointed at once; every other tile stays in the store until
  // the served map loads it (TileBacking). The error is the store's own one-line message.
  static Result<std::unique_ptr<MapPersistence>> Open(const StorageConfig& config,
                                                      const MapParams& params, TerrainMap& map);

  // ChangeJournal: appends the change to the scan log (durable as configured); marks tiles.
  Status Record(const ChangeRecord& change) override;
  void Applied(std::span<const TileKey> tiles) override;

  // Calls `on_over_limit` (from the applying worker, without locks held) whenever more than
  // `tiles` tiles are changed since the last capture: under a memory bound, checkpoints must
  // come often enough that their copies stay small. Call before any change is applied.
  void SetDirtyLimit(size_t tiles, std::function<void()> on_over_limit);
  bool dirty_over_limit() const;
  size_t dirty_tiles() const;

  // At a barrier: copies the tiles changed since the last capture; `version` is the applied
  // version (every change up to it is in the map, none above). Waits while an earlier capture
  // is not written yet; the result must be passed to Write() (or dropped) promptly.
  CapturedCheckpoint Capture(const MapStore& map, uint64_t version);
  // Outside the barrier. On failure the tiles stay marked for the next checkpoint.
  Status Write(CapturedCheckpoint captured);

  // Reads and checks every stored tile without keeping it, so that damage is found and
  // reported (CorruptTiles(), Info) before a query or scan meets it; tiles are otherwise read
  // only on demand. Returns early once `stop` is set.
  struct VerifyReport {
    uint64_t tiles = 0;
    uint64_t corrupt = 0;
    uint64_t unreadable = 0;  // I/O errors
    double seconds = 0;
    bool stopped = false;
  };
  VerifyReport VerifyStoredTiles(const std::atomic<bool>& stop) const;

  // TileBacking: the stored tiles, as of the last written checkpoint.
  bool IsStored(TileKey key) const override;
  void StoredIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const override;
  void ForEachStored(const std::function<void(TileKey, const StoredTile&)>& fn) const override;
  Result<std::unique_ptr<Tile>> Load(TileKey key) const override { return store_->LoadTile(key); }
  uint64_t durable_version() const override { return durable_version_.load(); }

  // After a failed write the store refuses every write until it is resumed. Call at a barrier:
  // TileStore::Resume() needs no other call in flight, and only changes call the store.
  // OK if nothing had failed or the store accepts writes again.
  Status ResumeIfFailed();
  bool write_failed() const { return write_failed_.load(); }

  const storage::RecoveryReport& recovery() const { return recovery_; }
  storage::TileStore& store() { return *store_; }
  uint64_t map_version() const { return store_->map_version(); }
  std::map<std::string, uint64_t> RobotSequences() const { return store_->log().RobotSequences(); }
  uint64_t checkpoint_version() const { return store_->checkpoint_version(); }
  std::vector<TileKey> CorruptTiles() const { return store_->CorruptTiles(); }
  const std::string& directory() const { return store_->directory(); }
  std::string durability() const;
  storage::StoreCounters counters() const { return store_->counters(); }

 private:
  explicit MapPersistence(std::unique_ptr<storage::TileStore> store) : store_(std::move(store)) {}

  std::unique_ptr<storage::TileStore> store_;
  storage::RecoveryReport recovery_;
  std::atomic<bool> write_failed_{false};
  std::shared_ptr<std::binary_semaphore> checkpoint_order_ =
      std::make_shared<std::binary_semaphore>(1);
  mutable std::mutex dirty_mu_;
  std::set<TileKey> dirty_;  // changed since the last capture
  size_t dirty_limit_ = 0;   // 0: none
  std::function<void()> on_dirty_over_limit_;
  // The store's tile index in memory, updated after each checkpoint is written and before
  // durable_version_ moves past it.
  mutable std::shared_mutex stored_mu_;
  std::map<TileKey, StoredTile> stored_;
  std::atomic<uint64_t> durable_version_{0};
};

}  // namespace bgkmap
