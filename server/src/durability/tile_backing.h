// Where the tiles of the served map live when they are not in memory. The served map loads
// tiles from it on demand and evicts clean tiles back to it (they are already there).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

class TileBacking {
 public:
  // Thread-safe; every answer is as of the last completed checkpoint.
  virtual bool IsStored(TileKey key) const = 0;
  // Appends the stored keys with min <= key <= max coordinate-wise, in (x, y) order.
  virtual void StoredIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const = 0;
  virtual void ForEachStored(const std::function<void(TileKey, const TileSummary&)>& fn) const = 0;
  // The stored tile's summary; nullopt if it is not stored.
  virtual std::optional<TileSummary> StoredSummary(TileKey key) const = 0;
  // The stored tile (null if none); DataLoss for a tile that fails its checksum.
  virtual Result<std::unique_ptr<Tile>> Load(TileKey key) const = 0;
  // Every change up to this version is in the stored tiles: a tile in memory whose version is
  // at or below it holds exactly what the store holds (it is clean and may be dropped).
  virtual uint64_t durable_version() const = 0;

 protected:
  ~TileBacking() = default;
};

}  // namespace bgkmap
