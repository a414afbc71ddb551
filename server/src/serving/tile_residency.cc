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
                             uint64_t memory_limit_bytes, std::function<void()> on_over_limit)
    : table_(table),
      backing_(backing),
      persists_(persists),
      memory_limit_bytes_(persists ? memory_limit_bytes : 0),
      on_over_limit_(std::move(on_over_limit)) {}

void TileResidency::SignalIfOverLimit() const {
  if (memory_limit_bytes_ == 0 || !on_over_limit_) return;
  if (table_.resident_tiles() * table_.TileBytes() > memory_limit_bytes_) on_over_limit_();
}

std::vector<TileKey> TileResidency::KeysIn(TileKey min, TileKey max) const {
  std::vector<TileKey> keys = table_.ListTiles(min, max);
  backing_.StoredIn(min, max, &keys);
  SortUnique(&keys);
  return keys;
}

Result<TileResidency::Pins> TileResidency::Pin(std::vector<TileKey> keys, bool strict) {
  Pins pins;
  if (!persists_) return pins;  // everything is in memory, nothing is evicted
  {
    std::lock_guard lock(mu_);
    const uint64_t now = ++use_clock_;
    for (TileKey k : keys) {
      Use& u = uses_[k];
      ++u.pins;
      u.last_use = now;
    }
  }
  pins.owner_ = this;
  pins.keys_ = std::move(keys);

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
  if (loaded.empty()) return pins;
  table_.InsertLoaded(loaded);
  tiles_loaded_.fetch_add(loaded.size());
  SignalIfOverLimit();
  return pins;
}

Result<TileResidency::Pins> TileResidency::PinScan(const PreparedScan& scan) {
  if (!persists_) return Pins();  // (the merged key list costs a sort per scan)
  std::vector<TileKey> keys = scan.ChangeableTiles();
  keys.insert(keys.end(), scan.read_tiles.begin(), scan.read_tiles.end());
  SortUnique(&keys);
  return Pin(std::move(keys), /*strict=*/false);
}

Result<TileResidency::Pins> TileResidency::PinRange(TileKey min, TileKey max, bool strict) {
  if (!persists_) return Pins();
  return Pin(KeysIn(min, max), strict);
}

void TileResidency::Unpin(const std::vector<TileKey>& keys) {
  std::lock_guard lock(mu_);
  for (TileKey k : keys) {
    auto it = uses_.find(k);
    if (it != uses_.end() && it->second.pins > 0) --it->second.pins;
  }
}

uint64_t TileResidency::Evict(uint64_t target_bytes) {
  const uint64_t per_tile = table_.TileBytes();
  if (!persists_) return table_.resident_tiles() * per_tile;
  const uint64_t durable = backing_.durable_version();
  // Held throughout: no tile can be pinned (and so changed) between choosing and erasing it.
  std::lock_guard lock(mu_);
  std::vector<std::pair<uint64_t, TileKey>> victims;  // (last use, key)
  std::unordered_map<TileKey, Use, TileKeyHash> kept;
  table_.ForEachResident([&](TileKey k, uint64_t version) {
    auto it = uses_.find(k);
    const bool pinned = it != uses_.end() && it->second.pins > 0;
    if (it != uses_.end()) kept.emplace(k, it->second);
    if (pinned || version > durable) return;  // in use, or changed since the last checkpoint
    victims.emplace_back(it == uses_.end() ? 0 : it->second.last_use, k);
  });
  // Forget the recency of tiles no longer in memory, unless pinned (a load in progress).
  for (const auto& [k, u] : uses_) {
    if (u.pins > 0) kept.emplace(k, u);
  }
  uses_ = std::move(kept);
  const uint64_t count = table_.resident_tiles();
  if (count * per_tile <= target_bytes) return count * per_tile;
  std::sort(victims.begin(), victims.end());
  const uint64_t target_tiles = target_bytes / per_tile;
  const size_t n = static_cast<size_t>(std::min<uint64_t>(victims.size(), count - target_tiles));
  std::vector<TileKey> evicted;
  evicted.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    evicted.push_back(victims[i].second);
    uses_.erase(victims[i].second);
  }
  table_.Erase(evicted);
  tiles_evicted_.fetch_add(evicted.size());
  return table_.resident_tiles() * per_tile;
}

ResidencyStats TileResidency::Stats() const {
  ResidencyStats r;
  r.resident_tiles = table_.resident_tiles();
  r.resident_bytes = r.resident_tiles * table_.TileBytes();
  r.tiles_loaded = tiles_loaded_.load();
  r.tiles_evicted = tiles_evicted_.load();
  return r;
}

}  // namespace bgkmap
