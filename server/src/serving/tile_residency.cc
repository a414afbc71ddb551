#include "serving/tile_residency.h"

#include <algorithm>

namespace bgkmap {
namespace {

void SortUnique(std::vector<TileKey>* keys) {
  std::sort(keys->begin(), keys->end());
  keys->erase(std::unique(keys->begin(), keys->end()), keys->end());
}

}  // namespace

TileResidency::Pins::Pins(Pins&& other) noexcept
    : owner_(other.owner_), keys_(std::move(other.keys_)) {
  other.owner_ = nullptr;
}

TileResidency::Pins& TileResidency::Pins::operator=(Pins&& other) noexcept {
  if (this != &other) {
    Release();
    owner_ = other.owner_;
    keys_ = std::move(other.keys_);
    other.owner_ = nullptr;
  }
  return *this;
}

void TileResidency::Pins::Release() {
  if (owner_ != nullptr) owner_->Unpin(keys_);
  owner_ = nullptr;
  keys_.clear();
}

TileResidency::TileResidency(TileTable& table, const StoredTiles& backing, bool persists,
                             uint64_t memory_limit_bytes, std::function<void()> on_over_limit,
                             uint64_t dense_limit_bytes, std::chrono::milliseconds pack_after_idle)
    : table_(table),
      backing_(backing),
      persists_(persists),
      dense_limit_bytes_(dense_limit_bytes),
      pack_after_idle_(pack_after_idle),
      tracks_(persists || dense_limit_bytes > 0),
      memory_limit_bytes_(persists ? memory_limit_bytes : 0),
      on_over_limit_(std::move(on_over_limit)) {}

void TileResidency::SignalIfOverLimit() const {
  if (!on_over_limit_) return;
  const bool over_memory = memory_limit_bytes_ != 0 && table_.ResidentBytes() > memory_limit_bytes_;
  const bool over_dense = dense_limit_bytes_ != 0 && table_.DenseBytes() > dense_limit_bytes_;
  if (over_memory || over_dense) on_over_limit_();
}

std::vector<TileKey> TileResidency::KeysIn(TileKey min, TileKey max) const {
  std::vector<TileKey> keys = table_.ListTiles(min, max);
  backing_.StoredIn(min, max, &keys);
  SortUnique(&keys);
  return keys;
}

Result<TileResidency::Pins> TileResidency::Pin(std::vector<TileKey> keys, bool strict) {
  Pins pins;
  if (!tracks_) return pins;  // everything is in memory and dense
  {
    std::lock_guard lock(mu_);
    PinLocked(keys);
  }
  pins.owner_ = this;
  pins.keys_ = std::move(keys);
  // Pinned, so Evict() packs none of them from here on: dense until the pins go.
  table_.Unpack(pins.keys_);
  if (!persists_) {
    SignalIfOverLimit();  // (the dense tiles grew)
    return pins;
  }

  // Pinned tiles in memory stay there; load the stored ones that are not.
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> loaded;
  for (TileKey k : table_.NotResident(pins.keys_)) {
    if (!backing_.IsStored(k)) continue;
    Result<std::unique_ptr<Tile>> tile = backing_.Load(k);
    if (!tile.ok()) {
      if (tile.status().code() == Status::Code::kDataLoss && !strict) continue;
      return tile.status();  // `pins` unpins
    }
    if (*tile != nullptr) loaded.emplace_back(k, std::move(tile).value());
  }
  if (!loaded.empty()) {
    table_.InsertLoaded(loaded);
    tiles_loaded_.fetch_add(loaded.size());
  }
  SignalIfOverLimit();
  return pins;
}

void TileResidency::PinLocked(const std::vector<TileKey>& keys) {
  const auto at = std::chrono::steady_clock::now();
  const uint64_t now = ++use_clock_;
  for (TileKey k : keys) {
    Use& u = uses_[k];
    ++u.pins;
    u.last_use = now;
    u.used_at = at;
  }
}

std::optional<TileResidency::Pins> TileResidency::TryPinInMemory(std::vector<TileKey> keys) {
  Pins pins;
  if (!tracks_) return pins;
  {
    std::unique_lock lock(mu_, std::try_to_lock);
    if (!lock.owns_lock()) return std::nullopt;
    PinLocked(keys);
  }
  pins.owner_ = this;
  pins.keys_ = std::move(keys);
  // Pinned: none of them is evicted from here on, so what is checked now holds.
  if (persists_) {
    for (TileKey k : table_.NotResident(pins.keys_)) {
      if (backing_.IsStored(k)) return std::nullopt;  // (`pins` unpins)
    }
  }
  return pins;
}

Result<TileResidency::Pins> TileResidency::PinScan(const PreparedScan& scan) {
  if (!tracks_) return Pins();  // (the merged key list costs a sort per scan)
  std::vector<TileKey> keys = scan.ChangeableTiles();
  keys.insert(keys.end(), scan.read_tiles.begin(), scan.read_tiles.end());
  SortUnique(&keys);
  return Pin(std::move(keys), /*strict=*/false);
}

Result<TileResidency::Pins> TileResidency::PinRange(TileKey min, TileKey max, bool strict) {
  if (!tracks_) return Pins();
  return Pin(KeysIn(min, max), strict);
}

void TileResidency::Unpin(const std::vector<TileKey>& keys) {
  std::lock_guard lock(mu_);
  for (TileKey k : keys) {
    auto it = uses_.find(k);
    if (it != uses_.end() && it->second.pins > 0) --it->second.pins;
  }
}

TileResidency::Candidates TileResidency::CollectLocked() {
  const uint64_t durable = persists_ ? backing_.durable_version() : 0;
  const auto idle_since = std::chrono::steady_clock::now() - pack_after_idle_;
  Candidates out;
  std::unordered_map<TileKey, Use, TileKeyHash> kept;
  table_.ForEachResident([&](const TileTable::ResidentTile& t) {
    auto it = uses_.find(t.key);
    const bool pinned = it != uses_.end() && it->second.pins > 0;
    if (it != uses_.end()) kept.emplace(t.key, it->second);
    if (pinned) return;  // in use
    const uint64_t last_use = it == uses_.end() ? 0 : it->second.last_use;
    const bool idle = it == uses_.end() || it->second.used_at <= idle_since;
    if (!t.packed && idle) out.dense.emplace_back(last_use, t.key);
    // Changed since the last checkpoint: not evictable.
    if (persists_ && t.version <= durable) out.clean.emplace_back(last_use, t.key, t.bytes);
  });
  // Forget the recency of tiles no longer in memory, unless pinned (a load in progress).
  for (const auto& [k, u] : uses_) {
    if (u.pins > 0) kept.emplace(k, u);
  }
  uses_ = std::move(kept);
  return out;
}

bool TileResidency::PackLocked(std::vector<std::pair<uint64_t, TileKey>>& dense) {
  const uint64_t held = table_.DenseBytes();
  if (dense_limit_bytes_ == 0 || held <= dense_limit_bytes_) return false;
  // Down to 80% of the budget, so that packing runs in batches rather than after every scan.
  const uint64_t per_tile = table_.TileBytes();
  const uint64_t excess = held - dense_limit_bytes_ / 10 * 8;
  const size_t n =
      static_cast<size_t>(std::min<uint64_t>(dense.size(), (excess + per_tile - 1) / per_tile));
  std::partial_sort(dense.begin(), dense.begin() + static_cast<std::ptrdiff_t>(n), dense.end());
  // In small batches: each holds the table lock exclusively while it packs.
  constexpr size_t kBatch = 16;
  std::vector<TileKey> batch;
  for (size_t i = 0; i < n; i += kBatch) {
    batch.clear();
    for (size_t j = i; j < std::min(n, i + kBatch); ++j) batch.push_back(dense[j].second);
    table_.Pack(batch);
  }
  tiles_packed_.fetch_add(n);
  return n > 0;
}

uint64_t TileResidency::Evict(uint64_t target_bytes) {
  if (!tracks_) return table_.ResidentBytes();
  // Held throughout: no tile can be pinned (and so changed, or unpacked) between choosing and
  // packing or erasing it.
  std::lock_guard lock(mu_);
  Candidates c = CollectLocked();
  if (PackLocked(c.dense) && persists_) c = CollectLocked();  // the packed tiles' new sizes
  if (!persists_) return table_.ResidentBytes();
  uint64_t held = table_.ResidentBytes();
  if (held <= target_bytes) return held;
  std::sort(c.clean.begin(), c.clean.end());
  std::vector<TileKey> evicted;
  for (const auto& [last_use, key, bytes] : c.clean) {
    if (held <= target_bytes) break;
    held -= std::min(held, bytes);
    evicted.push_back(key);
    uses_.erase(key);
  }
  table_.Erase(evicted);
  tiles_evicted_.fetch_add(evicted.size());
  return table_.ResidentBytes();
}

ResidencyStats TileResidency::Stats() const {
  ResidencyStats r;
  r.resident_tiles = table_.resident_tiles();
  r.resident_bytes = table_.ResidentBytes();
  r.packed_tiles = table_.packed_tiles();
  r.tiles_loaded = tiles_loaded_.load();
  r.tiles_evicted = tiles_evicted_.load();
  r.tiles_packed = tiles_packed_.load();
  return r;
}

}  // namespace bgkmap
