// The served map's tiles and the locks that make every change atomic for readers. Changes are
// ordered by ChangeScheduler, which never runs two conflicting ones at once; readers may run at
// any time and see every change either completely or not at all. Which tiles are in memory is
// TileResidency's business; what the served map answers is ServedMap's.
//
// Locks, always taken in this order:
//   1. gate_ (changes shared; map-wide reads and exclusive changes exclusive, with priority over
//      new scans),
//   2. tile locks (TileLockTable, ascending keys): a scan holds its write tiles exclusive, a
//      reader holds the tiles it reads shared,
//   3. (TileResidency's lock, taken by eviction before the table lock)
//   4. table_mu_ (the tile hash table): exclusive only while tiles are created or erased; readers
//      take it shared in short bands, so a large query never stalls ingestion for long.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <shared_mutex>
#include <span>
#include <utility>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/core/tile_summary.h"
#include "serving/shared_tasks.h"
#include "serving/tile_lock_table.h"
#include "serving/writer_priority_mutex.h"

namespace bgkmap {

// How one scan's integration is cut into bands (core/scan_bands.h) that run on the ingest
// workers: a dense scan then takes the cores the other scans leave idle. The map is the same bit
// for bit either way.
struct ScanBandOptions {
  int bands = 1;                 // most bands per scan (1: every scan whole)
  size_t cells_per_band = 8192;  // observed cells a band needs at least (fewer: not worth a cut)
  Offer offer;                   // hands a band to the workers (RunSharingWithPool)
};

class TileTable final {
 public:
  // `keep_cleared`: a tile a clear empties stays (all zero, stamped) until a checkpoint deletes
  // its stored copy; otherwise the uncleared stored tile could be loaded back.
  TileTable(std::unique_ptr<TerrainMap> map, bool keep_cleared, ScanBandOptions bands = {});

  const MapParams& params() const { return map_->params(); }
  const GridGeometry& geometry() const { return map_->geometry(); }
  // Memory of one dense tile (Tile::MemoryBytes of a dense tile of this map).
  uint64_t TileBytes() const;
  uint64_t resident_tiles() const { return resident_.load(); }
  uint64_t packed_tiles() const { return packed_tiles_.load(); }
  // Real bytes of the tiles in memory (what the memory bound counts): TileBytes() for each dense
  // tile, Tile::MemoryBytes() for each packed one; and those of the dense tiles alone.
  uint64_t ResidentBytes() const { return DenseBytes() + packed_bytes_.load(); }
  uint64_t DenseBytes() const {
    const uint64_t all = resident_.load(), packed = packed_tiles_.load();
    return (all > packed ? all - packed : 0) * TileBytes();  // (read apart: never below 0)
  }

  // Changes, with their tiles pinned. A scan holds its write tiles exclusively; the others hold
  // the whole map exclusively (call them at a scheduler barrier).
  ScanReport ApplyScan(const PreparedScan& scan, uint64_t version);
  // Returns the tiles that changed.
  std::vector<TileKey> ClearBox(const CellBox& box, uint64_t version);
  // OutOfRange naming the first tile and cell where adding `tiles` to the map's tiles would
  // give a statistic that is not finite (an overflow: the map would then answer NaN, and its
  // own archive would be refused as impossible); OK if every sum stays finite. Call at a
  // barrier (no change in flight) before AddTiles().
  Status CheckSumsFinite(std::span<const TileKey> keys, std::span<const Tile* const> tiles) const;
  // Adds each tile's statistics into the map (a merge: sums), stamped with `version`.
  void AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                uint64_t version);
  // Sets the tiles at `keys` to bitwise copies of `tiles` (null: none, so a stored tile is
  // current again): the undo of an AddTiles() with copies taken before it.
  void ReplaceTiles(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles);

  // Read locks. A reader holds them while it pins and reads.
  TileLockTable::Guard LockShared(std::span<const TileKey> keys);
  std::optional<TileLockTable::Guard> TryLockShared(std::span<const TileKey> keys) {
    return tile_locks_.TryLockShared(keys);
  }
  TileLockTable::Guard LockRangeShared(TileKey min, TileKey max);
  // Reads, under the caller's tile locks (and pins).
  Raster ReadRegion(const CellBox& box, const std::vector<Layer>& layers, int stride) const;
  std::vector<CellEstimate> ReadCells(std::span<const CellIndex> cells) const;
  // The tile's cells at stride 1 and its version (0: no such tile).
  std::pair<Raster, uint64_t> ReadTile(TileKey key, const std::vector<Layer>& layers) const;

  // At a barrier: bitwise copies of the tiles at `keys` (null where there is none in memory),
  // and the keys of the tiles in memory with min <= key <= max, sorted.
  std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const;
  // CopyTiles(), every copy packed (tile.h): costs the stored cells, not the tiles' area.
  std::vector<std::unique_ptr<Tile>> CopyTilesPacked(std::span<const TileKey> keys) const;
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const;
  // The keys of `keys` not in memory.
  std::vector<TileKey> NotResident(std::span<const TileKey> keys) const;
  // Summaries of every tile in memory.
  std::vector<std::pair<TileKey, TileSummary>> SummarizeResident() const;
  // Summaries of the tiles at `keys` (nullopt: not in memory), under the caller's tile locks.
  std::vector<std::optional<TileSummary>> SummarizeIfResident(std::span<const TileKey> keys) const;

  // For TileResidency: inserts loaded tiles not in memory yet (another operation may have
  // loaded, even changed, one meanwhile: that one stays); erases tiles.
  void InsertLoaded(std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>& loaded);
  struct ResidentTile {
    TileKey key;
    uint64_t version = 0;
    bool packed = false;
    uint64_t bytes = 0;  // Tile::MemoryBytes()
  };
  void ForEachResident(const std::function<void(const ResidentTile&)>& fn) const;
  void Erase(std::span<const TileKey> keys);
  // For TileResidency: packs the tiles at `keys` that are dense (only tiles no operation has
  // pinned: nothing changes them, and the readers that do not pin read either form), and makes
  // dense again the ones that are packed (for an operation that has just pinned them: the engine
  // and the pinned readers work on dense tiles). Both under the table lock held exclusively, so
  // no reader sees a tile change form; the statistics stay bit for bit.
  void Pack(std::span<const TileKey> keys);
  void Unpack(std::span<const TileKey> keys);

  // A consistent copy of every tile in memory (non-empty ones), with the map's version, and
  // the keys of all tiles in memory.
  std::unique_ptr<TerrainMap> CopyResident(uint64_t version, std::set<TileKey>* resident) const;

  // Most ApplyScan() calls ever inside Integrate() at once.
  uint32_t peak_parallel_integrations() const { return peak_integrations_.load(); }
  // Scans integrated in bands (ScanBandOptions).
  uint64_t banded_scans() const { return banded_scans_.load(); }

 private:
  // Call with table_mu_ held after the tile table changed size.
  void NoteTileCount() { resident_.store(map_->tile_count()); }
  // With table_mu_ held exclusively: the tile at `key`, if packed, made dense (a change is about
  // to touch it); its packed bytes forgotten before it is replaced or erased, counted after.
  void UnpackLocked(TileKey key);
  void ForgetPackedLocked(TileKey key);
  void CountPackedLocked(TileKey key);
  // Integrates `scan` into its window: in bands when it is large enough and `alone` (no other
  // scan integrating, so the workers may be free), whole otherwise.
  ScanReport Integrate(const PreparedScan& scan, const TileWindow& window, uint64_t version,
                       bool alone);

  std::unique_ptr<TerrainMap> map_;
  const bool keep_cleared_;
  std::atomic<uint64_t> resident_{0};
  // Written under table_mu_ held exclusively.
  std::atomic<uint64_t> packed_tiles_{0};
  std::atomic<uint64_t> packed_bytes_{0};
  mutable WriterPriorityMutex gate_;
  TileLockTable tile_locks_;
  mutable std::shared_mutex table_mu_;
  std::atomic<uint32_t> integrations_{0};
  std::atomic<uint32_t> peak_integrations_{0};
  const ScanBandOptions bands_;
  std::atomic<uint64_t> banded_scans_{0};
};

}  // namespace bgkmap
