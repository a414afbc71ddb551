#include "durability/store_durability.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "bgkmap/storage/log_record.h"
#include "bgkmap/storage/tile_snapshot.h"

namespace bgkmap {
namespace {

// The stored tiles of a snapshot taken right after a checkpoint.
class SnapshotTiles final : public TileSource {
 public:
  SnapshotTiles(std::unique_ptr<storage::TileSnapshot> snapshot, std::vector<TileKey> keys)
      : snapshot_(std::move(snapshot)), keys_(std::move(keys)) {}
  const std::vector<TileKey>& keys() const override { return keys_; }
  Result<std::unique_ptr<Tile>> Take(size_t i) override { return snapshot_->LoadTile(keys_[i]); }

 private:
  std::unique_ptr<storage::TileSnapshot> snapshot_;
  std::vector<TileKey> keys_;
};

}  // namespace

Result<std::unique_ptr<StoreDurability>> StoreDurability::Open(const StorageConfig& config,
                                                               const MapParams& params,
                                                               TerrainMap& map) {
  storage::StoreOptions options;
  Result<storage::Durability> durability = storage::ParseDurability(config.durability);
  if (!durability.ok()) return durability.status();
  options.durability = *durability;
  options.periodic_sync_ms = config.periodic_sync_ms;
  Result<std::unique_ptr<storage::TileStore>> store =
      storage::TileStore::Open(config.data_dir, options, params);
  if (!store.ok()) return store.status();
  std::unique_ptr<StoreDurability> d(new StoreDurability(std::move(store).value()));
  storage::TileStore& ts = *d->store_;

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
    if (Status s = ts.Checkpoint(ts.map_version(), updates); !s.ok()) return s;
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
  return store_->log().RobotSequences();
}

Status StoreDurability::Record(const ChangeRecord& change) {
  // The stamp is informational; a sender's absurd seconds must not overflow.
  int64_t stamp_ns = 0;
  if (__builtin_mul_overflow(change.stamp.seconds, int64_t{1'000'000'000}, &stamp_ns) ||
      __builtin_add_overflow(stamp_ns, int64_t{change.stamp.nanos}, &stamp_ns)) {
    stamp_ns = 0;
  }
  storage::LogRecord record = change.scan != nullptr
                                  ? storage::LogRecord::Scan(change.version, change.robot_id,
                                                             change.sequence, change.scan, stamp_ns)
                                  : storage::LogRecord::Clear(change.version, change.clear_box);
  Status s = store_->log().Append(record);
  if (s.code() == Status::Code::kIoError) write_failed_.store(true);
  return s;
}

Status StoreDurability::WriteCheckpoint(uint64_t version, std::span<const TileKey> keys,
                                        std::span<const std::unique_ptr<Tile>> tiles) {
  if (version <= store_->checkpoint_version() && keys.empty()) return Status::Ok();
  std::vector<storage::TileUpdate> updates;
  updates.reserve(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) updates.push_back({keys[i], tiles[i].get()});
  Status s = store_->Checkpoint(version, updates);
  if (s.code() == Status::Code::kIoError) write_failed_.store(true);
  if (!s.ok()) return s;
  index_.Update(GridGeometry(store_->params().resolution, store_->params().tile_size), keys, tiles);
  durable_version_.store(std::max(durable_version_.load(), version));
  return s;
}

Status StoreDurability::Resume() {
  if (!write_failed_.load() && store_->log().write_failure().ok()) return Status::Ok();
  Status s = store_->Resume();
  if (s.ok()) write_failed_.store(false);
  return s;
}

Result<std::unique_ptr<TileSource>> StoreDurability::OpenTileSource(TileKey min, TileKey max,
                                                                    const TileCopier&) {
  // Called right after a checkpoint at the applied version: the store holds the map exactly.
  std::unique_ptr<storage::TileSnapshot> snapshot = store_->NewSnapshot();
  Result<std::vector<storage::StoredTileInfo>> listed = snapshot->ListTiles(min, max);
  if (!listed.ok()) return listed.status();
  std::vector<TileKey> keys;
  keys.reserve(listed->size());
  for (const storage::StoredTileInfo& info : *listed) keys.push_back(info.key);
  return std::unique_ptr<TileSource>(new SnapshotTiles(std::move(snapshot), std::move(keys)));
}

Durability::ScratchDirectory StoreDurability::scratch_directory() const {
  return {store_->directory() + "/tmp", /*exclusive=*/true};
}

std::optional<StoreStatus> StoreDurability::store_status(bool with_disk_usage) const {
  StoreStatus s;
  s.directory = store_->directory();
  s.durability = durability_name();
  s.checkpoint_version = store_->checkpoint_version();
  s.corrupt_tiles = store_->CorruptTiles().size();
  s.write_failed = write_failed_.load();
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
    Result<std::unique_ptr<Tile>> tile = store_->LoadTile(k);  // marks a corrupt tile
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
