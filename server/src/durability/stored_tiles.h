// The tiles of the served map that live outside memory (Durability's third concern). The
// served map loads them on demand and evicts clean tiles back (they are already there); a tile
// that fails its checksum is listed, so queries never answer from it.
#pragma once

#include <atomic>
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

class StoredTiles {
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

  // Stored tiles found failing their checksum, sorted: queries must not answer from them.
  virtual std::vector<TileKey> CorruptTiles() const = 0;
  // Reads and checks every stored tile without keeping it, so that damage is found and
  // reported (CorruptTiles(), Info) before a query or scan meets it; tiles are otherwise read
  // only on demand. Returns early once `stop` is set.
  struct VerifyReport {
    uint64_t tiles = 0;
    uint64_t corrupt = 0;
    uint64_t unreadable = 0;  // I/O errors
    double seconds = 0;
    bool stopped = false;
  };
  virtual VerifyReport VerifyStoredTiles(const std::atomic<bool>& stop) const = 0;

 protected:
  ~StoredTiles() = default;
};

}  // namespace bgkmap
