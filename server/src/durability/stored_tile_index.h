// The store's tile index in memory: which tiles are stored and their summaries, so the served
// map knows what it may load, and counts what it has not loaded, without reading the store.
// Updated after each checkpoint is written. Thread-safe.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <shared_mutex>
#include <span>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

class StoredTileIndex {
 public:
  void Set(TileKey key, const TileSummary& summary);
  // After a checkpoint wrote `tiles` at `keys` (null or no known cell: deleted from the store).
  void Update(const GridGeometry& geometry, std::span<const TileKey> keys,
              std::span<const std::unique_ptr<Tile>> tiles);

  bool Contains(TileKey key) const;
  std::optional<TileSummary> Find(TileKey key) const;
  // Appends the keys with min <= key <= max coordinate-wise, in (x, y) order.
  void KeysIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const;
  std::vector<TileKey> Keys() const;
  void ForEach(const std::function<void(TileKey, const TileSummary&)>& fn) const;

 private:
  mutable std::shared_mutex mu_;
  std::map<TileKey, TileSummary> tiles_;  // sorted by x, then y
};

}  // namespace bgkmap
