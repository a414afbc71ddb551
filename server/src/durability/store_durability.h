// Durability in the persistent store (storage/, storage.data_dir): opens and recovers it at
// start, journals every change to the scan log before it is applied, writes checkpoints of the
// changed tiles, and serves the stored tiles back (StoredTiles) from an index kept in memory.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <shared_mutex>
#include <string>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/server/server_config.h"
#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_store.h"
#include "durability/durability.h"
#include "durability/stored_tile_index.h"

namespace bgkmap {

class StoreDurability final : public Durability {
 public:
  // Opens (or creates) the store in config.data_dir and brings `map` (empty, created with
  // `params`) to the store's latest state: the tiles the log after the last checkpoint touches
  // are replayed into it and checkpointed at once; every other tile stays in the store until
  // the served map loads it. `georeference` is the configured one (empty: keep the stored
  // one); a store tied to another refuses it (TileStore::Open). The error is the store's own
  // one-line message.
  static Result<std::unique_ptr<StoreDurability>> Open(const StorageConfig& config,
                                                       const MapParams& params,
                                                       const Georeference& georeference,
                                                       TerrainMap& map);

  bool persists() const override { return true; }
  uint64_t recovered_version() const override { return recovery_.map_version; }
  std::map<std::string, uint64_t> LoggedRobotSequences() const override;
  Status RetireRobot(const std::string& robot_id) override {
    std::shared_lock lock(reopen_mu_);
    return store_->log().RetireRobot(robot_id);
  }
  Status Record(const ChangeRecord& change) override;
  bool retains_scans() const override;
  uint64_t retained_records_bound() const override;
  Result<CorrectionPlan> PlanCorrection(const std::string& robot_id,
                                        const std::map<uint64_t, Pose>& poses,
                                        const CorrectionRange& remove) const override;
  Result<storage::Reintegration> Reintegrate(const CorrectionPlan& plan, uint64_t end,
                                             bool plan_only) const override;
  Status RecordCorrection(const CorrectionPlan& plan, uint64_t version) override;
  // The next checkpoint at or above `version` follows a change made outside the log (an
  // import): earlier checkpoints can no longer be rebuilt from.
  void NoteChangeOutsideLog(uint64_t version) override { outside_log_version_.store(version); }
  Status WriteCheckpoint(uint64_t version, std::span<const TileKey> keys,
                         std::span<const std::unique_ptr<Tile>> tiles) override;
  bool write_failed() const override { return write_failed_.load() || writes_paused_for_space(); }
  Status Resume() override;
  bool writes_paused_for_space() const override;
  // Half of storage.retention_mb written since the last checkpoint (never without retention).
  bool checkpoint_due_by_size() const override;
  std::vector<TileKey> DeferredTiles() const override { return deferred_; }
  Status AdmitScratch(uint64_t bytes) override;
  Result<std::unique_ptr<TilesAtVersion>> OpenTileSource(TileKey min, TileKey max,
                                                         const ResidentTiles& map) override;
  std::vector<TileKey> CorruptTiles() const override { return store_->CorruptTiles(); }
  ScratchDirectory scratch_directory() const override;
  std::optional<StoreStatus> store_status(bool with_disk_usage) const override;
  Georeference georeference() const override { return store_->georeference(); }
  Status AdoptGeoreference(const Georeference& georeference) override {
    std::shared_lock lock(reopen_mu_);
    return store_->AdoptGeoreference(georeference);
  }

  // StoredTiles: the stored tiles, as of the last written checkpoint.
  bool IsStored(TileKey key) const override { return index_.Contains(key); }
  void StoredIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const override {
    index_.KeysIn(min, max, keys);
  }
  void ForEachStored(const std::function<void(TileKey, const TileSummary&)>& fn) const override {
    index_.ForEach(fn);
  }
  std::optional<TileSummary> StoredSummary(TileKey key) const override { return index_.Find(key); }
  Result<std::unique_ptr<Tile>> Load(TileKey key) const override {
    std::shared_lock lock(reopen_mu_);
    return store_->LoadTile(key);
  }
  uint64_t durable_version() const override { return durable_version_.load(); }

  VerifyReport VerifyStoredTiles(const std::atomic<bool>& stop) const override;

  const storage::RecoveryReport& recovery() const { return recovery_; }
  const std::string& directory() const { return store_->directory(); }
  std::string durability_name() const;

 private:
  explicit StoreDurability(std::unique_ptr<storage::TileStore> store) : store_(std::move(store)) {}
  // After a write (or a refusal): logs the start and the end of a pause for space, once each.
  void NotePause(const Status& outcome);

  std::unique_ptr<storage::TileStore> store_;
  // Resume() may reopen the database (a read-only start, a failed write): exclusive then; every
  // other use of the database, queries' tile loads included, holds it shared.
  mutable std::shared_mutex reopen_mu_;
  storage::RecoveryReport recovery_;
  std::atomic<bool> write_failed_{false};  // the store latched a failed write
  std::atomic<bool> pause_logged_{false};  // event=storage_full logged, resumption not yet
  std::vector<TileKey> deferred_;          // set at Open()
  StoredTileIndex index_;
  // Moves past a checkpoint's version only after the index holds its tiles.
  std::atomic<uint64_t> durable_version_{0};
  std::atomic<uint64_t> outside_log_version_{0};  // NoteChangeOutsideLog(), until checkpointed
};

}  // namespace bgkmap
