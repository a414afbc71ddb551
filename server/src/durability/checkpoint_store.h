// Checkpoints: the changed tiles stored at a version, after which the journal below it may go;
// and the export sources read right after one (Durability's second concern).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"

namespace bgkmap {

// The tiles in memory, copied at a barrier (no change in flight): the served map's table.
class ResidentTiles {
 public:
  // Bitwise copies of the tiles at `keys` (null where the map has none in memory), in either
  // form (tile.h).
  virtual std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const = 0;
  // Keys of the tiles in memory with min <= key <= max, sorted.
  virtual std::vector<TileKey> ListTiles(TileKey min, TileKey max) const = 0;

 protected:
  ~ResidentTiles() = default;
};

// The map's tiles as of one version, readable while the map changes on (an export).
class TilesAtVersion {
 public:
  virtual ~TilesAtVersion() = default;
  // The keys to read, sorted.
  virtual const std::vector<TileKey>& keys() const = 0;
  // The tile at keys()[i] (null: none); DataLoss naming a stored tile that fails its checksum.
  virtual Result<std::unique_ptr<Tile>> Take(size_t i) = 0;
};

class CheckpointStore {
 public:
  // Stores the tiles captured at `version` (null: the tile is gone). Checkpoints arrive in the
  // order they were captured (Checkpointer).
  virtual Status WriteCheckpoint(uint64_t version, std::span<const TileKey> keys,
                                 std::span<const std::unique_ptr<Tile>> tiles) = 0;
  // After a failed write, or while writes are paused for lack of space, the store refuses
  // writes until resumed. Call at a barrier; OK if nothing had failed or writes are accepted
  // again.
  virtual bool write_failed() const = 0;
  virtual Status Resume() = 0;
  // Writes are refused for lack of free space (a full disk): logged quietly, retried each second.
  virtual bool writes_paused_for_space() const { return false; }
  // The journal written since the last checkpoint has grown past its share of the retention
  // bound: checkpoint now, before the interval is up, so retention can trim it (issue 25).
  virtual bool checkpoint_due_by_size() const { return false; }
  // Tiles the map holds newer than the store whose checkpoint was deferred at start (recovered
  // on a full disk): the first checkpoint after writes resume must write them.
  virtual std::vector<TileKey> DeferredTiles() const { return {}; }

  // At a barrier, right after a checkpoint at the applied version: the tiles in [min, max] as
  // of now, readable after the barrier ends. `map` supplies them where nothing is stored.
  virtual Result<std::unique_ptr<TilesAtVersion>> OpenTileSource(TileKey min, TileKey max,
                                                                 const ResidentTiles& map) = 0;

 protected:
  ~CheckpointStore() = default;
};

}  // namespace bgkmap
