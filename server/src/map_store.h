// The served map and the locks around it. Writers are called by ScanScheduler, which never runs
// two conflicting changes at once; readers may run at any time and see every change either
// completely or not at all.
//
// With a TileBacking (the persistent store), only part of the map need be in memory: every
// operation first pins the tiles it touches, which loads the stored ones not in memory, and
// Evict() drops clean, unpinned tiles, least recently used first, to stay under a byte bound.
// A tile in memory is authoritative; a tile not in memory is what the backing stores.
//
// Locks, always taken in this order:
//   1. gate_ (changes shared; map-wide reads and clears exclusive, with priority over new scans),
//   2. tile locks (TileLockTable, ascending keys): a scan holds its write tiles exclusive, a
//      reader holds the tiles it reads shared,
//   3. residency_mu_ (pin counts and recency),
//   4. table_mu_ (the tile hash table): exclusive only while tiles are created or erased; readers
//      take it shared in short bands, so a large query never stalls ingestion for long.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <span>
#include <unordered_map>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "tile_backing.h"
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

struct ResidencyStats {
  uint64_t resident_tiles = 0;
  uint64_t resident_bytes = 0;  // tile memory (TerrainMap::TileMemoryBytes)
  uint64_t tiles_loaded = 0;    // from the backing, since start
  uint64_t tiles_evicted = 0;   // since start
};

class MapStore {
 public:
  // Tiles an operation uses: they stay in memory until the pins are destroyed.
  class Pins {
   public:
    Pins() = default;
    Pins(Pins&& other) noexcept;
    Pins& operator=(Pins&& other) noexcept;
    Pins(const Pins&) = delete;
    Pins& operator=(const Pins&) = delete;
    ~Pins() { Release(); }
    void Release();

   private:
    friend class MapStore;
    const MapStore* store_ = nullptr;
    std::vector<TileKey> keys_;
  };

  explicit MapStore(std::unique_ptr<TerrainMap> map);

  // Before any other call. Tiles not in memory are loaded from `backing`; when the tiles in
  // memory exceed `memory_limit_bytes` (0: never), `on_over_limit` is called (from the thread
  // that crossed it, without locks held) so that someone calls Evict().
  void AttachBacking(const TileBacking* backing, uint64_t memory_limit_bytes,
                     std::function<void()> on_over_limit);

  const MapParams& params() const { return map_->params(); }
  const GridGeometry& geometry() const { return map_->geometry(); }

  // Pins what a change will touch (a scan's write and read tiles, or every tile in a clear's
  // box), loading stored tiles. Call before the change is journaled: an error (the store cannot
  // be read) means the change must be refused. A stored tile that fails its checksum is left
  // out (the change starts it afresh, as if it were empty; the store keeps it listed corrupt).
  Result<Pins> PinForScan(const PreparedScan& scan) const;
  Result<Pins> PinForClear(const CellBox& box) const;

  // Writers (serialised per tile by the scheduler), with the change's tiles pinned.
  ScanReport ApplyScan(const PreparedScan& scan, uint64_t version);
  std::vector<TileKey> ClearBox(const CellBox& box, uint64_t version);
  void SetMapVersion(uint64_t version);
  // Import: adds each tile's statistics into the map (a merge: sums) and stamps the tiles with
  // `version`. Call at a scheduler barrier (no change in flight); readers see all or nothing.
  // The tiles are loaded from the backing first: DataLoss naming a stored tile that fails its
  // checksum (nothing is added), IoError if the store cannot be read.
  Status AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                  uint64_t version);
  // Sets the tiles at `keys` to bitwise copies of `tiles` (null: no tile), e.g. to undo an
  // AddTiles() whose checkpoint failed with copies taken by CopyTiles() before it. At a barrier.
  void ReplaceTiles(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles);

  // Readers. With a backing they load the stored tiles they need: IoError if the store cannot
  // be read, DataLoss naming a tile that fails its checksum (never an answer without it).
  Result<Raster> ReadRegion(const CellBox& box, const std::vector<Layer>& layers, int stride) const;
  Result<std::vector<CellEstimate>> ReadCells(std::span<const CellIndex> cells) const;
  Result<TileContent> ReadTile(TileKey key, const std::vector<Layer>& layers) const;
  // Keys of the tiles with min <= key <= max coordinate-wise, in memory or stored, sorted.
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const;
  MapSummary Summarize() const;

  // Drops clean, unpinned tiles, least recently used first, until the tiles in memory take at
  // most `target_bytes`. Returns the bytes still held. Tiles changed since the backing's last
  // checkpoint stay: a checkpoint makes them clean.
  uint64_t Evict(uint64_t target_bytes);
  ResidencyStats Residency() const;
  // Memory of one tile in the table (what the bound counts).
  uint64_t TileBytes() const;

  // Most ApplyScan() calls ever inside Integrate() at once.
  uint32_t peak_parallel_integrations() const { return peak_integrations_.load(); }

  // Copies of the tiles at `keys` (null where the map has none), for a checkpoint. Call with no
  // writer running (at a scheduler barrier).
  std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const;

  // For tests and shutdown reports: a consistent copy of every tile, stored ones included.
  std::unique_ptr<TerrainMap> Snapshot() const;

 private:
  struct Use {
    uint32_t pins = 0;
    uint64_t last_use = 0;
  };

  // Pins `keys` (sorted, unique) and loads the stored ones not in memory. `strict`: a tile
  // failing its checksum is an error (readers) rather than left out (changes).
  Result<Pins> PinKeys(std::vector<TileKey> keys, bool strict) const;
  void Unpin(std::span<const TileKey> keys) const;
  std::vector<TileKey> ListResident(TileKey min, TileKey max) const;
  // The keys in [min, max] that are in memory or stored (sorted, unique).
  std::vector<TileKey> KeysIn(TileKey min, TileKey max) const;
  // Call with table_mu_ held after the tile table changed size.
  void NoteTileCount() const;
  void SignalIfOverLimit() const;

  std::unique_ptr<TerrainMap> map_;
  const TileBacking* backing_ = nullptr;
  uint64_t memory_limit_bytes_ = 0;
  std::function<void()> on_over_limit_;
  mutable std::mutex residency_mu_;
  mutable std::unordered_map<TileKey, Use, TileKeyHash> uses_;
  mutable uint64_t use_clock_ = 0;
  mutable std::atomic<uint64_t> resident_tiles_{0};
  mutable std::atomic<uint64_t> tiles_loaded_{0};
  std::atomic<uint64_t> tiles_evicted_{0};
  mutable WriterPriorityMutex gate_;
  mutable TileLockTable tile_locks_;
  mutable std::shared_mutex table_mu_;
  std::atomic<uint32_t> integrations_{0};
  std::atomic<uint32_t> peak_integrations_{0};
};

}  // namespace bgkmap
