#include "map_persistence.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "bgkmap/storage/log_record.h"

namespace bgkmap {
namespace {

// The tiles the log after the checkpoint changes: what recovery rewrote (or erased) in `map`.
Result<std::set<TileKey>> TilesTouchedByLog(const storage::TileStore& store,
                                            const GridGeometry& geometry) {
  std::set<TileKey> touched;
  Status s = store.log().ForEach(
      store.checkpoint_version(), [&](uint64_t, Result<storage::LogRecord> record) -> Status {
        if (!record.ok()) return Status::Ok();  // reported by RecoverMap
        if (record->type == storage::LogRecord::Type::kScan) {
          touched.insert(record->scan->write_tiles.begin(), record->scan->write_tiles.end());
          return Status::Ok();
        }
        const CellBox& box = record->clear_box;
        Result<std::vector<storage::StoredTileInfo>> stored =
            store.ListTiles(geometry.TileOf(box.min), geometry.TileOf(box.max));
        if (!stored.ok()) return stored.status();
        for (const storage::StoredTileInfo& t : *stored) touched.insert(t.key);
        return Status::Ok();
      });
  if (!s.ok()) return s;
  return touched;
}

}  // namespace

Result<std::unique_ptr<MapPersistence>> MapPersistence::Open(const StorageConfig& config,
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
  std::unique_ptr<MapPersistence> p(new MapPersistence(std::move(store).value()));
  storage::TileStore& ts = *p->store_;

  Result<std::set<TileKey>> touched = TilesTouchedByLog(ts, map.geometry());
  if (!touched.ok()) return touched.status();
  Result<storage::RecoveryReport> report = storage::RecoverMap(ts, map);
  if (!report.ok()) return report.status();
  p->recovery_ = *report;

  // Checkpoint the recovered tiles at once: the log becomes empty, and tiles that replayed
  // clears erased are deleted from the store before a query could load them back.
  // Corrupt tiles are left out so that they stay listed as corrupt.
  if (!touched->empty()) {
    const std::vector<TileKey> corrupt = ts.CorruptTiles();
    std::vector<storage::TileUpdate> updates;
    for (TileKey k : *touched) {
      if (std::binary_search(corrupt.begin(), corrupt.end(), k)) continue;
      updates.push_back({k, map.FindTile(k)});
    }
    if (Status s = ts.Checkpoint(ts.map_version(), updates); !s.ok()) return s;
  }
  // Every other tile is current in the store and is loaded when the served map needs it.
  Result<std::vector<storage::StoredTileInfo>> stored = ts.ListTiles();
  if (!stored.ok()) return stored.status();
  for (const storage::StoredTileInfo& t : *stored) {
    p->stored_[t.key] = {t.known_cells, t.known_box};
  }
  p->durable_version_.store(ts.checkpoint_version());
  return p;
}

Status MapPersistence::Record(const ChangeRecord& change) {
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

Status MapPersistence::ResumeIfFailed() {
  if (!write_failed_.load() && store_->log().write_failure().ok()) return Status::Ok();
  Status s = store_->Resume();
  if (s.ok()) write_failed_.store(false);
  return s;
}

void MapPersistence::Applied(std::span<const TileKey> tiles) {
  bool over = false;
  {
    std::lock_guard lock(dirty_mu_);
    dirty_.insert(tiles.begin(), tiles.end());
    over = dirty_limit_ > 0 && dirty_.size() > dirty_limit_;
  }
  if (over) on_dirty_over_limit_();
}

void MapPersistence::SetDirtyLimit(size_t tiles, std::function<void()> on_over_limit) {
  std::lock_guard lock(dirty_mu_);
  dirty_limit_ = tiles;
  on_dirty_over_limit_ = std::move(on_over_limit);
}

size_t MapPersistence::dirty_tiles() const {
  std::lock_guard lock(dirty_mu_);
  return dirty_.size();
}

bool MapPersistence::dirty_over_limit() const {
  std::lock_guard lock(dirty_mu_);
  return dirty_limit_ > 0 && dirty_.size() > dirty_limit_;
}

CapturedCheckpoint MapPersistence::Capture(const MapStore& map, uint64_t version) {
  CapturedCheckpoint c;
  checkpoint_order_->acquire();
  c.order = std::shared_ptr<std::binary_semaphore>(
      checkpoint_order_.get(), [keep = checkpoint_order_](auto* slot) { slot->release(); });
  c.version = version;
  {
    std::lock_guard lock(dirty_mu_);
    c.keys.assign(dirty_.begin(), dirty_.end());
    dirty_.clear();
  }
  c.tiles = map.CopyTiles(c.keys);
  return c;
}

Status MapPersistence::Write(CapturedCheckpoint captured) {
  if (captured.version <= store_->checkpoint_version() && captured.keys.empty()) {
    return Status::Ok();
  }
  std::vector<storage::TileUpdate> updates;
  updates.reserve(captured.keys.size());
  for (size_t i = 0; i < captured.keys.size(); ++i) {
    updates.push_back({captured.keys[i], captured.tiles[i].get()});
  }
  Status s = store_->Checkpoint(captured.version, updates);
  if (s.code() == Status::Code::kIoError) write_failed_.store(true);
  if (!s.ok()) {
    // The log still holds these changes; the next checkpoint writes the tiles again.
    std::lock_guard lock(dirty_mu_);
    dirty_.insert(captured.keys.begin(), captured.keys.end());
    return s;
  }
  {
    std::unique_lock lock(stored_mu_);
    for (const storage::TileUpdate& u : updates) {
      const CellBox local = u.tile != nullptr ? u.tile->KnownLocalBox() : CellBox{};
      if (local.empty()) {
        stored_.erase(u.key);
        continue;
      }
      const int t = store_->params().tile_size;
      const CellIndex o{u.key.x * t, u.key.y * t};
      stored_[u.key] = {
          static_cast<uint32_t>(u.tile->CountKnown()),
          {{o.x + local.min.x, o.y + local.min.y}, {o.x + local.max.x, o.y + local.max.y}}};
    }
  }
  durable_version_.store(std::max(durable_version_.load(), captured.version));
  return s;
}

MapPersistence::VerifyReport MapPersistence::VerifyStoredTiles(
    const std::atomic<bool>& stop) const {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<TileKey> keys;
  {
    std::shared_lock lock(stored_mu_);
    keys.reserve(stored_.size());
    for (const auto& entry : stored_) keys.push_back(entry.first);
  }
  VerifyReport r;
  for (TileKey k : keys) {
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

bool MapPersistence::IsStored(TileKey key) const {
  std::shared_lock lock(stored_mu_);
  return stored_.contains(key);
}

void MapPersistence::StoredIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const {
  if (min.x > max.x || min.y > max.y) return;
  std::shared_lock lock(stored_mu_);
  // Keys sort by x, then y: one contiguous run per column.
  for (auto it = stored_.lower_bound(min); it != stored_.end() && it->first.x <= max.x;) {
    const TileKey k = it->first;
    if (k.y < min.y) {
      it = stored_.lower_bound({k.x, min.y});
    } else if (k.y > max.y) {
      if (k.x == INT32_MAX) break;
      it = stored_.lower_bound({k.x + 1, min.y});
    } else {
      keys->push_back(k);
      ++it;
    }
  }
}

void MapPersistence::ForEachStored(
    const std::function<void(TileKey, const StoredTile&)>& fn) const {
  std::shared_lock lock(stored_mu_);
  for (const auto& [k, t] : stored_) fn(k, t);
}

std::string MapPersistence::durability() const {
  return std::string(storage::DurabilityName(store_->options().durability));
}

}  // namespace bgkmap
