#include "map_store.h"

#include <algorithm>
#include <mutex>
#include <string>

namespace bgkmap {
namespace {

// Cells read per hold of the table lock: small enough that tile creation never waits long.
constexpr int64_t kCellsPerBand = 1 << 18;

void SortUnique(std::vector<TileKey>* keys) {
  std::sort(keys->begin(), keys->end());
  keys->erase(std::unique(keys->begin(), keys->end()), keys->end());
}

}  // namespace

MapStore::Pins::Pins(Pins&& other) noexcept : store_(other.store_), keys_(std::move(other.keys_)) {
  other.store_ = nullptr;
}

MapStore::Pins& MapStore::Pins::operator=(Pins&& other) noexcept {
  if (this != &other) {
    Release();
    store_ = other.store_;
    keys_ = std::move(other.keys_);
    other.store_ = nullptr;
  }
  return *this;
}

void MapStore::Pins::Release() {
  if (store_ != nullptr) store_->Unpin(keys_);
  store_ = nullptr;
  keys_.clear();
}

MapStore::MapStore(std::unique_ptr<TerrainMap> map) : map_(std::move(map)) {
  resident_tiles_.store(map_->tile_count());
}

void MapStore::AttachBacking(const TileBacking* backing, uint64_t memory_limit_bytes,
                             std::function<void()> on_over_limit) {
  backing_ = backing;
  memory_limit_bytes_ = backing != nullptr ? memory_limit_bytes : 0;
  on_over_limit_ = std::move(on_over_limit);
}

uint64_t MapStore::TileBytes() const {
  const uint64_t t = static_cast<uint64_t>(params().tile_size);
  return sizeof(Tile) + t * t * Tile::kBytesPerCell;
}

void MapStore::NoteTileCount() const { resident_tiles_.store(map_->tile_count()); }

void MapStore::SignalIfOverLimit() const {
  if (memory_limit_bytes_ == 0 || !on_over_limit_) return;
  if (resident_tiles_.load() * TileBytes() > memory_limit_bytes_) on_over_limit_();
}

std::vector<TileKey> MapStore::KeysIn(TileKey min, TileKey max) const {
  std::vector<TileKey> keys;
  const uint64_t resident = resident_tiles_.load();
  const uint64_t w = min.x <= max.x ? uint64_t(int64_t{max.x} - min.x + 1) : 0;
  const uint64_t h = min.y <= max.y ? uint64_t(int64_t{max.y} - min.y + 1) : 0;
  // (w, h <= resident first: the whole key space would overflow w * h.)
  if (w > 0 && h > 0 && w <= resident && h <= resident && w * h <= resident) {
    // A small range (a query's): look its keys up rather than walk every tile in memory.
    std::shared_lock table(table_mu_);
    for (int64_t x = min.x; x <= max.x; ++x) {  // 64-bit: max.x may be INT32_MAX
      for (int64_t y = min.y; y <= max.y; ++y) {
        const TileKey k{static_cast<int>(x), static_cast<int>(y)};
        if (map_->FindTile(k) != nullptr) keys.push_back(k);
      }
    }
  } else {
    keys = ListResident(min, max);
  }
  if (backing_ != nullptr) backing_->StoredIn(min, max, &keys);
  SortUnique(&keys);
  return keys;
}

Result<MapStore::Pins> MapStore::PinKeys(std::vector<TileKey> keys, bool strict) const {
  Pins pins;
  if (backing_ == nullptr) return pins;  // everything is in memory, nothing is evicted
  {
    std::lock_guard lock(residency_mu_);
    const uint64_t now = ++use_clock_;
    for (TileKey k : keys) {
      Use& u = uses_[k];
      ++u.pins;
      u.last_use = now;
    }
  }
  pins.store_ = this;
  pins.keys_ = std::move(keys);

  // Pinned tiles in memory stay there; load the stored ones that are not.
  std::vector<TileKey> missing;
  {
    std::shared_lock table(table_mu_);
    for (TileKey k : pins.keys_) {
      if (map_->FindTile(k) == nullptr && backing_->IsStored(k)) missing.push_back(k);
    }
  }
  if (missing.empty()) return pins;
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> loaded;
  for (TileKey k : missing) {
    Result<std::unique_ptr<Tile>> tile = backing_->Load(k);
    if (!tile.ok()) {
      if (tile.status().code() == Status::Code::kDataLoss && !strict) continue;
      return tile.status();  // `pins` unpins
    }
    if (*tile != nullptr) loaded.emplace_back(k, std::move(tile).value());
  }
  {
    std::unique_lock table(table_mu_);
    for (auto& [k, tile] : loaded) {
      // Another operation may have loaded (and even changed) it meanwhile: keep that one.
      if (map_->FindTile(k) == nullptr) map_->SetTile(k, *tile);
    }
    NoteTileCount();
  }
  tiles_loaded_.fetch_add(loaded.size());
  SignalIfOverLimit();
  return pins;
}

void MapStore::Unpin(std::span<const TileKey> keys) const {
  std::lock_guard lock(residency_mu_);
  for (TileKey k : keys) {
    auto it = uses_.find(k);
    if (it != uses_.end() && it->second.pins > 0) --it->second.pins;
  }
}

Result<MapStore::Pins> MapStore::PinForScan(const PreparedScan& scan) const {
  if (backing_ == nullptr) return Pins();
  std::vector<TileKey> keys = scan.write_tiles;
  keys.insert(keys.end(), scan.read_tiles.begin(), scan.read_tiles.end());
  SortUnique(&keys);
  return PinKeys(std::move(keys), /*strict=*/false);
}

Result<MapStore::Pins> MapStore::PinForClear(const CellBox& box) const {
  if (backing_ == nullptr || box.empty()) return Pins();
  const GridGeometry& g = geometry();
  return PinKeys(KeysIn(g.TileOf(box.min), g.TileOf(box.max)), /*strict=*/false);
}

uint64_t MapStore::Evict(uint64_t target_bytes) {
  const uint64_t per_tile = TileBytes();
  if (backing_ == nullptr) return resident_tiles_.load() * per_tile;
  const uint64_t durable = backing_->durable_version();
  std::lock_guard lock(residency_mu_);
  std::unique_lock table(table_mu_);
  // Forget the recency of tiles no longer in memory and not pinned.
  for (auto it = uses_.begin(); it != uses_.end();) {
    if (it->second.pins == 0 && map_->FindTile(it->first) == nullptr) {
      it = uses_.erase(it);
    } else {
      ++it;
    }
  }
  const uint64_t held = map_->tile_count() * per_tile;
  if (held <= target_bytes) return held;
  std::vector<std::pair<uint64_t, TileKey>> victims;  // (last use, key)
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    if (t.version() > durable) return;  // changed since the last checkpoint
    auto it = uses_.find(k);
    if (it == uses_.end()) {
      victims.emplace_back(0, k);
    } else if (it->second.pins == 0) {
      victims.emplace_back(it->second.last_use, k);
    }
  });
  std::sort(victims.begin(), victims.end());
  uint64_t count = map_->tile_count(), evicted = 0;
  for (const auto& [use, k] : victims) {
    if (count * per_tile <= target_bytes) break;
    map_->EraseTile(k);
    uses_.erase(k);
    --count;
    ++evicted;
  }
  NoteTileCount();
  tiles_evicted_.fetch_add(evicted);
  return count * per_tile;
}

ResidencyStats MapStore::Residency() const {
  ResidencyStats r;
  r.resident_tiles = resident_tiles_.load();
  r.resident_bytes = r.resident_tiles * TileBytes();
  r.tiles_loaded = tiles_loaded_.load();
  r.tiles_evicted = tiles_evicted_.load();
  return r;
}

ScanReport MapStore::ApplyScan(const PreparedScan& scan, uint64_t version) {
  std::shared_lock gate(gate_);
  // Read tiles need no lock: the scheduler runs no writer of them now, and readers only read.
  TileLockTable::Guard tiles = tile_locks_.Lock(scan.write_tiles, {});
  TileWindow window;
  {
    std::unique_lock table(table_mu_);
    window = map_->MakeWindow(scan);
    NoteTileCount();
  }
  // Integrate() touches only the window's tiles: no table lock, other scans run beside it.
  const uint32_t now = integrations_.fetch_add(1) + 1;
  uint32_t peak = peak_integrations_.load();
  while (now > peak && !peak_integrations_.compare_exchange_weak(peak, now)) {
  }
  ScanReport report = map_->Integrate(scan, window, version);
  integrations_.fetch_sub(1);
  SignalIfOverLimit();
  return report;
}

std::vector<TileKey> MapStore::ClearBox(const CellBox& box, uint64_t version) {
  std::unique_lock gate(gate_);  // no scan runs, so no tile appears meanwhile
  const GridGeometry& g = geometry();
  const std::vector<TileKey> existing = ListResident(g.TileOf(box.min), g.TileOf(box.max));
  TileLockTable::Guard tiles = tile_locks_.Lock(existing, {});
  std::unique_lock table(table_mu_);
  // With a backing, a tile the clear emptied stays in memory as an all-zero tile of this
  // version until a checkpoint deletes it from the store: dropping it now would let the stored
  // (uncleared) tile be loaded back. (Its version keeps it from eviction until then.)
  std::vector<TileKey> changed = map_->ClearBox(box, version, /*keep_empty=*/backing_ != nullptr);
  NoteTileCount();
  return changed;
}

void MapStore::SetMapVersion(uint64_t version) {
  std::unique_lock table(table_mu_);
  // Finishing workers report out of order; the map's version only moves forward.
  if (version > map_->version()) map_->set_version(version);
}

Status MapStore::AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                          uint64_t version) {
  std::vector<TileKey> sorted(keys.begin(), keys.end());
  SortUnique(&sorted);
  Result<Pins> pins = PinKeys(sorted, /*strict=*/true);  // never add onto a lost tile
  if (!pins.ok()) return pins.status();
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(sorted, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    map_->AddTile(keys[i], *tiles[i]);
    map_->FindMutableTile(keys[i])->set_version(version);
  }
  NoteTileCount();
  return Status::Ok();
}

void MapStore::ReplaceTiles(std::span<const TileKey> keys,
                            std::span<const std::unique_ptr<Tile>> tiles) {
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(keys, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    if (tiles[i] == nullptr) {
      map_->EraseTile(keys[i]);  // with a backing: the stored tile is current again
    } else {
      map_->SetTile(keys[i], *tiles[i]);
    }
  }
  NoteTileCount();
}

Result<Raster> MapStore::ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                                    int stride) const {
  const GridGeometry& g = geometry();
  const TileKey lo = g.TileOf(box.min), hi = g.TileOf(box.max);
  TileLockTable::Guard tiles = tile_locks_.LockRange(lo, hi);
  // Pinned under the tile locks: no scan can add a tile to the range meanwhile.
  Result<Pins> pins = PinKeys(backing_ != nullptr ? KeysIn(lo, hi) : std::vector<TileKey>{},
                              /*strict=*/true);
  if (!pins.ok()) return pins.status();

  // Bands of whole stride blocks, north to south, each read under its own table-lock hold.
  const int64_t band_rows = std::max<int64_t>(
      stride, (kCellsPerBand / std::max<int64_t>(box.width(), 1)) / stride * stride);
  Raster out;
  bool first = true;
  for (int64_t top = box.max.y; top >= box.min.y; top -= band_rows) {
    CellBox band = box;
    band.max.y = static_cast<int>(top);
    band.min.y = static_cast<int>(std::max<int64_t>(box.min.y, top - band_rows + 1));
    Raster part;
    {
      std::shared_lock table(table_mu_);
      part = ExtractRaster(*map_, band, layers, stride);
    }
    if (first) {
      out = std::move(part);
      out.box = box;
      first = false;
      continue;
    }
    out.rows += part.rows;
    for (size_t i = 0; i < out.data.size(); ++i) {
      out.data[i].insert(out.data[i].end(), part.data[i].begin(), part.data[i].end());
    }
  }
  return out;
}

Result<std::vector<CellEstimate>> MapStore::ReadCells(std::span<const CellIndex> cells) const {
  const GridGeometry& g = geometry();
  std::vector<TileKey> keys;
  keys.reserve(cells.size());
  for (CellIndex c : cells) keys.push_back(g.TileOf(c));
  SortUnique(&keys);
  TileLockTable::Guard tiles = tile_locks_.Lock({}, keys);
  Result<Pins> pins = PinKeys(keys, /*strict=*/true);
  if (!pins.ok()) return pins.status();
  std::shared_lock table(table_mu_);
  std::vector<CellEstimate> out;
  out.reserve(cells.size());
  for (CellIndex c : cells) out.push_back(map_->Estimate(c));
  return out;
}

Result<TileContent> MapStore::ReadTile(TileKey key, const std::vector<Layer>& layers) const {
  const TileKey one[] = {key};
  TileLockTable::Guard tiles = tile_locks_.Lock({}, one);
  Result<Pins> pins = PinKeys({key}, /*strict=*/true);
  if (!pins.ok()) return pins.status();
  std::shared_lock table(table_mu_);
  TileContent out;
  out.raster = ExtractRaster(*map_, geometry().TileBox(key), layers, 1);
  if (const Tile* t = map_->FindTile(key)) out.version = t->version();
  return out;
}

std::vector<TileKey> MapStore::ListResident(TileKey min, TileKey max) const {
  std::vector<TileKey> keys;
  std::shared_lock table(table_mu_);
  map_->ForEachTile([&](TileKey k, const Tile&) {
    if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) keys.push_back(k);
  });
  std::sort(keys.begin(), keys.end());
  return keys;
}

std::vector<TileKey> MapStore::ListTiles(TileKey min, TileKey max) const {
  return KeysIn(min, max);
}

MapSummary MapStore::Summarize() const {
  std::unique_lock gate(gate_);  // counts of whole scans only
  std::shared_lock table(table_mu_);
  MapSummary s;
  // Empty tiles (a clear leaves them until a checkpoint deletes them from the store) do not count.
  map_->ForEachTile([&](TileKey, const Tile& t) {
    const int known = t.CountKnown();
    s.tile_count += known > 0 ? 1 : 0;
    s.known_cells += static_cast<uint64_t>(known);
  });
  s.known_bounds = map_->KnownBounds();
  if (backing_ != nullptr) {
    // Stored tiles not in memory are clean: the store's summary of them is current.
    backing_->ForEachStored([&](TileKey k, const TileBacking::StoredTile& t) {
      if (map_->FindTile(k) != nullptr) return;
      ++s.tile_count;
      s.known_cells += t.known_cells;
      if (t.known_cells == 0) return;
      s.known_bounds.Extend(t.known_box.min);
      s.known_bounds.Extend(t.known_box.max);
    });
  }
  return s;
}

std::vector<std::unique_ptr<Tile>> MapStore::CopyTiles(std::span<const TileKey> keys) const {
  std::shared_lock table(table_mu_);
  std::vector<std::unique_ptr<Tile>> out;
  out.reserve(keys.size());
  for (TileKey k : keys) {
    const Tile* t = map_->FindTile(k);
    out.push_back(t == nullptr ? nullptr : std::make_unique<Tile>(*t));
  }
  return out;
}

std::unique_ptr<TerrainMap> MapStore::Snapshot() const {
  std::unique_lock gate(gate_);
  std::shared_lock table(table_mu_);
  Result<std::unique_ptr<TerrainMap>> copy = TerrainMap::Create(map_->params());
  std::unique_ptr<TerrainMap> out = std::move(copy).value();
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    if (!t.Empty()) out->SetTile(k, t);
  });
  if (backing_ != nullptr) {
    backing_->ForEachStored([&](TileKey k, const TileBacking::StoredTile&) {
      if (map_->FindTile(k) != nullptr) return;
      Result<std::unique_ptr<Tile>> tile = backing_->Load(k);
      if (tile.ok() && *tile != nullptr) out->SetTile(k, **tile);
    });
  }
  out->set_version(map_->version());
  return out;
}

}  // namespace bgkmap
