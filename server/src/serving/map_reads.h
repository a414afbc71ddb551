// The reads a query handler makes: answered by the served map on a single server, or by a
// cluster node that gathers the tiles from the partitions' owners (cluster/cluster_reads.h).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

struct TileContent {
  Raster raster;         // the tile's cells at stride 1
  uint64_t version = 0;  // of the tile's last change (0: the tile does not exist)
};

class MapReads {
 public:
  // The version the next reads will be at least at (the cluster: its log's last sequence).
  virtual uint64_t applied_version() const = 0;
  // IoError if the store cannot be read, DataLoss naming a corrupt tile, Unavailable if a
  // cluster partition has no shard serving it.
  virtual Result<Raster> ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                                    int stride) = 0;
  virtual Result<std::vector<CellEstimate>> ReadCells(std::span<const CellIndex> cells) = 0;
  // ReadCells() if it can answer at once, without waiting on a change, a lock or the store;
  // empty (call ReadCells() from a thread that may wait) otherwise. A short read on the thread
  // that received the call saves the wake-up of another (docs/server.md, "Concurrency").
  virtual std::optional<Result<std::vector<CellEstimate>>> TryReadCellsNow(
      std::span<const CellIndex> /*cells*/) {
    return std::nullopt;
  }
  // One tile's cells (what Watch sends). A cluster knows no per-tile version: it gives the log
  // sequence the tile was read at, which is at or after the tile's last change.
  virtual Result<TileContent> ReadTile(TileKey key, const std::vector<Layer>& layers) = 0;
  // Keys of the tiles that exist with min <= key <= max, sorted.
  virtual Result<std::vector<TileKey>> ListKnownTiles(TileKey min, TileKey max) = 0;

  // Region deltas (docs/server.md, "Region deltas"). Names this map's record of tile changes;
  // a since_version is only answered for the id it was read with (new at every start).
  virtual uint64_t history_id() const = 0;
  // The tiles with min <= key <= max (per axis) whose last change is after `since`, sorted by
  // key, each with the blocks (tile_blocks.h) that may have changed since (a superset of those
  // that did; TileBlocks::All() where only the tile is known), including tiles emptied or removed
  // since (read applied_version() first: every change up to it is then listed).
  // FailedPrecondition saying why if this map cannot answer `since` exactly (then the caller
  // answers the whole region).
  virtual Result<std::vector<ChangedTile>> TilesChangedSince(TileKey min, TileKey max,
                                                             uint64_t since) = 0;

 protected:
  ~MapReads() = default;
};

}  // namespace bgkmap
