#include "durability/store_durability.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "bgkmap/storage/free_space.h"
#include "bgkmap/storage/log_record.h"
#include "bgkmap/storage/tile_snapshot.h"
#include "durability/disk_sizing.h"

namespace bgkmap {
namespace {

// The stored tiles of a snapshot taken right after a checkpoint.
class SnapshotTiles final : public TilesAtVersion {
 public:
  SnapshotTiles(std::unique_ptr<storage::TileSnapshot> snapshot, std::vector<TileKey> keys)
      : snapshot_(std::move(snapshot)), keys_(std::move(keys)) {}
  const std::vector<TileKey>& keys() const override { return keys_; }
  Result<std::unique_ptr<Tile>> Take(size_t i) override { return snapshot_->LoadTile(keys_[i]); }

 private:
  std::unique_ptr<storage::TileSnapshot> snapshot_;
  std::vector<TileKey> keys_;
};

// The sizing rule (disk_sizing.h) against the free space plus what the store holds already.
void WarnIfUndersized(const storage::TileStore& store, const StorageConfig& config) {
  Result<uint64_t> free = storage::StatvfsFreeBytes(store.directory());
  if (!free.ok()) return;
  const storage::DiskUsage usage = store.Usage();
  const DiskSizing sizing = SizingFor(config.retention_mb, config.min_free_space_mb,
                                      store.options().memtable_bytes, usage.tile_bytes);
  const std::string why = CheckSizing(sizing, *free + usage.total_bytes);
  if (!why.empty()) {
    spdlog::warn("event=storage_undersized data_dir={} reason=\"{}\"", store.directory(), why);
  }
}

}  // namespace

Result<std::unique_ptr<StoreDurability>> StoreDurability::Open(const StorageConfig& config,
                                                               const MapParams& params,
                                                               const Georeference& georeference,
                                                               TerrainMap& map) {
  storage::StoreOptions options;
  Result<storage::Durability> durability = storage::ParseDurability(config.durability);
  if (!durability.ok()) return durability.status();
  options.durability = *durability;
  options.periodic_sync_ms = config.periodic_sync_ms;
  options.free_space.reserve_bytes = config.min_free_space_mb << 20;
  options.retention.max_bytes = config.retention_mb << 20;
  options.retention.max_age_ns = static_cast<int64_t>(config.retention_s * 1e9);
  // Under a memory bound RocksDB's block cache and memory tables take a share of it (an eighth
  // each, 8 to 32 MiB) rather than a fixed 32 MiB each: a small bound is a small machine.
  if (config.max_memory_mb > 0) {
    const uint64_t share = std::clamp<uint64_t>((config.max_memory_mb << 20) / 8, uint64_t{8} << 20,
                                                uint64_t{32} << 20);
    options.block_cache_bytes = share;
    options.memtable_bytes = share;
  }
  Result<std::unique_ptr<storage::TileStore>> store =
      storage::TileStore::Open(config.data_dir, options, params, georeference);
  if (!store.ok()) return store.status();
  std::unique_ptr<StoreDurability> d(new StoreDurability(std::move(store).value()));
  storage::TileStore& ts = *d->store_;
  WarnIfUndersized(ts, config);
  if (ts.read_only()) {
    spdlog::warn(
        "event=storage_read_only data_dir={} reason=\"{}\" detail=\"opened read-only: queries "
        "are answered, writes are refused until there is room (checked every second)\"",
        ts.directory(), ts.CheckFreeSpace().message());
    d->pause_logged_.store(true);
  }

  Result<storage::RecoveryReport> report = storage::RecoverMap(ts, map);
  if (!report.ok()) return report.status();
  d->recovery_ = *report;

  // Checkpoint the recovered tiles at once: the log becomes empty, and tiles that replayed
  // clears erased are deleted from the store before a query could load them back.
  // Corrupt tiles are left out so that they stay listed as corrupt.
  if (!report->touched_tiles.empty()) {
    const std::vector<TileKey> corrupt = ts.CorruptTiles();
    std::vector<storage::TileUpdate> updates;
    for (TileKey k : report->touched_tiles) {
      if (std::binary_search(corrupt.begin(), corrupt.end(), k)) continue;
      updates.push_back({k, map.FindTile(k)});
    }
    Status s = ts.read_only() ? ts.AdmitWrite(0) : ts.Checkpoint(ts.map_version(), updates);
    if (!s.ok() && !d->writes_paused_for_space()) return s;
    if (!s.ok()) {
      // No room for the checkpoint: the recovered tiles stay in memory, newer than the store,
      // and the first checkpoint after writes resume stores them (the log keeps their changes
      // meanwhile). A tile a replayed clear emptied is kept, empty, so that a query cannot load
      // the stored one back.
      for (const storage::TileUpdate& u : updates) {
        if (u.tile == nullptr) map.GetOrCreateTile(u.key).set_version(ts.map_version());
        d->deferred_.push_back(u.key);
      }
      spdlog::warn("event=recovery_checkpoint_deferred tiles={} reason=\"{}\"", updates.size(),
                   s.message());
    }
  }
  // Every other tile is current in the store and is loaded when the served map needs it.
  Result<std::vector<storage::StoredTileInfo>> stored = ts.ListTiles();
  if (!stored.ok()) return stored.status();
  for (const storage::StoredTileInfo& t : *stored) {
    d->index_.Set(t.key, {t.known_cells, t.known_box});
  }
  d->durable_version_.store(ts.checkpoint_version());
  return d;
}

std::map<std::string, uint64_t> StoreDurability::LoggedRobotSequences() const {
  std::shared_lock lock(reopen_mu_);
  return store_->log().RobotSequences();
}

Status StoreDurability::Record(const ChangeRecord& change) {
  std::shared_lock lock(reopen_mu_);
  // The scan's map time, as it was integrated (PrepareScanMessage): replay forgets with it.
  const int64_t stamp_ns = change.scan != nullptr ? change.scan->stamp_ns : 0;
  storage::LogRecord record = change.scan != nullptr
                                  ? storage::LogRecord::Scan(change.version, change.robot_id,
                                                             change.sequence, change.scan, stamp_ns)
                                  : storage::LogRecord::Clear(change.version, change.clear_box);
  record.raw_scan = change.raw_scan;
  Status s = store_->log().Append(record);
  if (!store_->log().write_failure().ok()) write_failed_.store(true);
  NotePause(s);
  return s;
}

bool StoreDurability::writes_paused_for_space() const {
  return store_->read_only() || store_->free_space().below_reserve();
}

bool StoreDurability::checkpoint_due_by_size() const {
  // Retention keeps at most its bound below the newest checkpoint, but never trims above it:
  // without this the journal since the checkpoint (robots x rate x scan size x interval) would
  // add to the bound unchecked. Half the bound between checkpoints keeps the total within
  // 1.5 x the bound (docs/storage.md, "Sizing").
  const uint64_t bound = store_->options().retention.max_bytes;
  return bound > 0 && store_->log().bytes_since_checkpoint() > bound / 2;
}

void StoreDurability::NotePause(const Status& outcome) {
  if (!outcome.ok() && writes_paused_for_space()) {
    if (!pause_logged_.exchange(true)) {
      spdlog::warn("event=storage_full reason=\"{}\" detail=\"writes refused, queries answered\"",
                   outcome.message());
    }
  } else if (outcome.ok() && !writes_paused_for_space() && pause_logged_.exchange(false)) {
    // (A write that frees space is admitted below the reserve: writes stay paused then.)
    spdlog::info("event=storage_resumed reason=\"free space above the reserve again\"");
  }
}

Status StoreDurability::AdmitScratch(uint64_t bytes) {
  std::shared_lock lock(reopen_mu_);
  Status s = store_->AdmitWrite(bytes);
  NotePause(s);
  return s;
}

Status StoreDurability::WriteCheckpoint(uint64_t version, std::span<const TileKey> keys,
                                        std::span<const std::unique_ptr<Tile>> tiles) {
  std::shared_lock lock(reopen_mu_);
  if (version <= store_->checkpoint_version() && keys.empty()) return Status::Ok();
  std::vector<storage::TileUpdate> updates;
  updates.reserve(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) updates.push_back({keys[i], tiles[i].get()});
  uint64_t outside = outside_log_version_.load();
  const bool rebase = outside != 0 && version >= outside;
  Status s = store_->Checkpoint(version, updates, rebase);
  if (s.ok() && rebase) outside_log_version_.compare_exchange_strong(outside, 0);
  if (!store_->log().write_failure().ok()) write_failed_.store(true);
  NotePause(s);
  if (!s.ok()) return s;
  index_.Update(GridGeometry(store_->params().resolution, store_->params().tile_size), keys, tiles);
  durable_version_.store(std::max(durable_version_.load(), version));
  return s;
}

Status StoreDurability::Resume() {
  std::unique_lock lock(reopen_mu_);
  if (!write_failed() && store_->log().write_failure().ok()) return Status::Ok();
  // Reopens a read-only store or one that latched a failure; either way only with the reserve
  // free, which is what writes paused for space wait for too.
  Status s = store_->Resume();
  if (s.ok()) s = store_->CheckFreeSpace();
  if (s.ok()) write_failed_.store(false);
  NotePause(s);
  return s;
}

Result<std::unique_ptr<TilesAtVersion>> StoreDurability::OpenTileSource(TileKey min, TileKey max,
                                                                        const ResidentTiles&) {
  std::shared_lock lock(reopen_mu_);
  // Called right after a checkpoint at the applied version: the store holds the map exactly.
  std::unique_ptr<storage::TileSnapshot> snapshot = store_->NewSnapshot();
  Result<std::vector<storage::StoredTileInfo>> listed = snapshot->ListTiles(min, max);
  if (!listed.ok()) return listed.status();
  std::vector<TileKey> keys;
  keys.reserve(listed->size());
  for (const storage::StoredTileInfo& info : *listed) keys.push_back(info.key);
  return std::unique_ptr<TilesAtVersion>(new SnapshotTiles(std::move(snapshot), std::move(keys)));
}

Durability::ScratchDirectory StoreDurability::scratch_directory() const {
  return {store_->directory() + "/tmp", /*exclusive=*/true};
}

std::optional<StoreStatus> StoreDurability::store_status(bool with_disk_usage) const {
  std::shared_lock lock(reopen_mu_);
  StoreStatus s;
  s.directory = store_->directory();
  s.durability = durability_name();
  s.checkpoint_version = store_->checkpoint_version();
  s.corrupt_tiles = store_->CorruptTiles().size();
  s.write_failed = write_failed_.load();
  s.writes_paused_for_space = writes_paused_for_space();
  s.read_only = store_->read_only();
  s.free_bytes = store_->free_space().free_bytes();
  s.reserve_bytes = store_->free_space().reserve_bytes();
  if (s.writes_paused_for_space) {
    s.paused_reason = (s.read_only ? "opened read-only on a full disk; " : "") +
                      std::string("data dir has ") + std::to_string(s.free_bytes >> 20) +
                      " MB free, below the reserve of " + std::to_string(s.reserve_bytes >> 20) +
                      " MB; writes resume when space is freed";
  }
  s.counters = store_->counters();
  if (with_disk_usage) s.usage = store_->Usage();
  return s;
}

std::string StoreDurability::durability_name() const {
  return std::string(storage::DurabilityName(store_->options().durability));
}

Durability::VerifyReport StoreDurability::VerifyStoredTiles(const std::atomic<bool>& stop) const {
  const auto t0 = std::chrono::steady_clock::now();
  VerifyReport r;
  for (TileKey k : index_.Keys()) {
    if (stop.load()) {
      r.stopped = true;
      break;
    }
    Result<std::unique_ptr<Tile>> tile = Load(k);  // marks a corrupt tile
    ++r.tiles;
    if (tile.ok()) continue;
    if (tile.status().code() == Status::Code::kDataLoss) {
      ++r.corrupt;
      spdlog::error("event=corrupt_tile tile=({},{}) reason=\"{}\"", k.x, k.y,
                    tile.status().message());
    } else {
      ++r.unreadable;
      spdlog::error("event=tile_unreadable tile=({},{}) reason=\"{}\"", k.x, k.y,
                    tile.status().message());
    }
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace bgkmap
