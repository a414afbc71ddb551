#include "durability/stored_tile_index.h"

#include <climits>
#include <mutex>

namespace bgkmap {

void StoredTileIndex::Set(TileKey key, const TileSummary& summary) {
  std::unique_lock lock(mu_);
  tiles_[key] = summary;
}

void StoredTileIndex::Update(const GridGeometry& geometry, std::span<const TileKey> keys,
                             std::span<const std::unique_ptr<Tile>> tiles) {
  std::unique_lock lock(mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    const TileSummary s = SummarizeTile(geometry, keys[i], tiles[i].get());
    if (s.known_cells == 0) {
      tiles_.erase(keys[i]);  // the checkpoint deletes an empty tile
    } else {
      tiles_[keys[i]] = s;
    }
  }
}

bool StoredTileIndex::Contains(TileKey key) const {
  std::shared_lock lock(mu_);
  return tiles_.contains(key);
}

std::optional<TileSummary> StoredTileIndex::Find(TileKey key) const {
  std::shared_lock lock(mu_);
  auto it = tiles_.find(key);
  if (it == tiles_.end()) return std::nullopt;
  return it->second;
}

void StoredTileIndex::KeysIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const {
  if (min.x > max.x || min.y > max.y) return;
  std::shared_lock lock(mu_);
  // Keys sort by x, then y: one contiguous run per column.
  for (auto it = tiles_.lower_bound(min); it != tiles_.end() && it->first.x <= max.x;) {
    const TileKey k = it->first;
    if (k.y < min.y) {
      it = tiles_.lower_bound({k.x, min.y});
    } else if (k.y > max.y) {
      if (k.x == INT_MAX) break;
      it = tiles_.lower_bound({k.x + 1, min.y});
    } else {
      keys->push_back(k);
      ++it;
    }
  }
}

std::vector<TileKey> StoredTileIndex::Keys() const {
  std::shared_lock lock(mu_);
  std::vector<TileKey> keys;
  keys.reserve(tiles_.size());
  for (const auto& entry : tiles_) keys.push_back(entry.first);
  return keys;
}

void StoredTileIndex::ForEach(const std::function<void(TileKey, const TileSummary&)>& fn) const {
  std::shared_lock lock(mu_);
  for (const auto& [k, t] : tiles_) fn(k, t);
}

}  // namespace bgkmap
