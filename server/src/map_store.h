// The served map and the locks around it. Writers are called by ScanScheduler, which never runs
// two conflicting changes at once; readers may run at any time and see every change either
// completely or not at all.
//
// Locks, always taken in this order:
//   1. gate_ (changes shared; map-wide reads and clears exclusive, with priority over new scans),
//   2. tile locks (TileLockTable, ascending keys): a scan holds its write tiles exclusive, a
//      reader holds the tiles it reads shared,
//   3. table_mu_ (the tile hash table): exclusive only while tiles are created or erased; readers
//      take it shared in short bands, so a large query never stalls ingestion for long.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <shared_mutex>
#include <span>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "tile_lock_table.h"
#include "writer_priority_mutex.h"

namespace bgkmap {

struct MapSummary {
  uint64_t tile_count = 0;
  uint64_t known_cells = 0;
  CellBox known_bounds;  // empty when nothing is known
};

struct TileContent {
  Raster raster;         // the tile's cells at stride 1
  uint64_t version = 0;  // of the tile's last change (0: the tile does not exist)
};

class MapStore {
 public:
  explicit MapStore(std::unique_ptr<TerrainMap> map);

  const MapParams& params() const { return map_->params(); }
  const GridGeometry& geometry() const { return map_->geometry(); }

  // Writers (serialised per tile by the scheduler).
  ScanReport ApplyScan(const PreparedScan& scan, uint64_t version);
  std::vector<TileKey> ClearBox(const CellBox& box, uint64_t version);
  void SetMapVersion(uint64_t version);
  // Import: adds each tile's statistics into the map (a merge: sums) and stamps the tiles with
  // `version`. Call at a scheduler barrier (no change in flight); readers see all or nothing.
  void AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                uint64_t version);
  // Sets the tiles at `keys` to bitwise copies of `tiles` (null: no tile), e.g. to undo an
  // AddTiles() whose checkpoint failed with copies taken by CopyTiles() before it. At a barrier.
  void ReplaceTiles(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles);

  // Readers.
  Raster ReadRegion(const CellBox& box, const std::vector<Layer>& layers, int stride) const;
  std::vector<CellEstimate> ReadCells(std::span<const CellIndex> cells) const;
  TileContent ReadTile(TileKey key, const std::vector<Layer>& layers) const;
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const;
  MapSummary Summarize() const;

  // Most ApplyScan() calls ever inside Integrate() at once.
  uint32_t peak_parallel_integrations() const { return peak_integrations_.load(); }

  // Copies of the tiles at `keys` (null where the map has none), for a checkpoint. Call with no
  // writer running (at a scheduler barrier).
  std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const;

  // For tests and shutdown reports: a consistent copy of every tile.
  std::unique_ptr<TerrainMap> Snapshot() const;

 private:
  std::unique_ptr<TerrainMap> map_;
  mutable WriterPriorityMutex gate_;
  mutable TileLockTable tile_locks_;
  mutable std::shared_mutex table_mu_;
  std::atomic<uint32_t> integrations_{0};
  std::atomic<uint32_t> peak_integrations_{0};
};

}  // namespace bgkmap
