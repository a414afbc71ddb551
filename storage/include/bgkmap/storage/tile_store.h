// A map's persistent store: tiles as of the last checkpoint, the scan log after it, and the map
// metadata, in one RocksDB database in one directory.
//
// The store's state is "the map at checkpoint_version()" (the tiles) plus "every change after
// it" (the log). The served map is rebuilt from both by RecoverMap() (recovery.h), which loads
// only the tiles the log touches; every other tile is current in the store and is loaded on
// demand with LoadTile(). Nothing reads all tiles at open.
//
// Thread-safe: every method but Resume() may be called concurrently.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/storage/free_space.h"
#include "bgkmap/storage/map_metadata.h"
#include "bgkmap/storage/scan_log.h"
#include "bgkmap/storage/store_options.h"

namespace rocksdb {
class Snapshot;
class WriteBatch;
}  // namespace rocksdb

namespace bgkmap::storage {

struct StoreDb;
class TileSnapshot;

// One tile of a checkpoint. A null or all-zero tile deletes the key (a cleared tile).
struct TileUpdate {
  TileKey key;
  const Tile* tile = nullptr;  // borrowed for the duration of the call
};

// What the tile index knows of a stored tile without reading it.
struct StoredTileInfo {
  TileKey key;
  uint64_t version = 0;        // of the tile's last change
  uint32_t known_cells = 0;    // Tile::CountKnown()
  uint32_t encoded_bytes = 0;  // before RocksDB's block compression
  CellBox known_box;           // of the known cells, in map cells
};

struct StoreCounters {
  uint64_t tiles_loaded = 0;
  uint64_t tiles_written = 0;
  uint64_t tiles_deleted = 0;
  uint64_t checkpoints = 0;
  uint64_t corrupt_tiles = 0;        // distinct tiles found corrupt since open
  uint64_t corrupt_log_records = 0;  // log records found corrupt since open
  uint64_t log_records_appended = 0;
  uint64_t log_bytes_appended = 0;
  uint64_t write_errors = 0;  // failed appends and checkpoints
  // Writes refused before they were tried: below the free-space reserve, or read-only.
  uint64_t writes_refused_for_space = 0;
  // Compactions of the ranges checkpoints dropped (TileStore::Checkpoint), and those that failed.
  uint64_t reclaims = 0;
  uint64_t reclaim_errors = 0;
};

struct DiskUsage {
  uint64_t tile_bytes = 0;     // SST files of the tiles column family
  uint64_t log_bytes = 0;      // SST files of the log column family
  uint64_t sources_bytes = 0;  // SST files of the retained raw scans
  uint64_t history_bytes = 0;  // SST files of the retained tile history
  uint64_t wal_bytes = 0;      // write-ahead log files
  uint64_t total_bytes = 0;    // every file in the store's directory (WAL included)
};

class TileStore {
 public:
  // Opens the store in `dir`, creating it (with `params`) if the directory holds none and
  // options.create_if_missing. Reopening checks the stored parameters against `params`:
  // FailedPrecondition naming the first differing key if the statistics are incompatible
  // (CheckParamsCompatible); otherwise the stored derived-layer parameters are updated to
  // `params`. A non-empty `georeference` is stored if the store has none (a new one, or one
  // written before georeferences were kept); one that differs from the stored is refused with
  // FailedPrecondition naming the key (CheckGeoreferenceCompatible); an empty one keeps the
  // stored. FailedPrecondition as well for a store of a newer format or a directory in use
  // by another process; IoError/DataLoss if the database cannot be opened.
  // With a free-space reserve (options.free_space) and less than it free: an existing store
  // opens read-only (nothing is written, not even the parameters; every write is refused until
  // Resume() finds the space back), and creating a store is refused with IoError.
  static Result<std::unique_ptr<TileStore>> Open(const std::string& dir,
                                                 const StoreOptions& options,
                                                 const MapParams& params,
                                                 const Georeference& georeference = {});
  // Opens an existing store with the parameters it holds (FailedPrecondition if there is none).
  static Result<std::unique_ptr<TileStore>> OpenExisting(const std::string& dir,
                                                         const StoreOptions& options);

  // Stops the periodic sync, syncs the log and closes the database.
  ~TileStore();
  TileStore(const TileStore&) = delete;
  TileStore& operator=(const TileStore&) = delete;

  const std::string& directory() const { return dir_; }
  const MapParams& params() const { return params_; }
  // Where the map frame sits (empty: a local frame).
  Georeference georeference() const;
  // Ties a map in a local frame to `georeference` for good (an import of a georeferenced
  // archive): OK at once if it is empty or already the stored one; FailedPrecondition naming
  // the key if the store has another; IoError if the write is refused or fails.
  Status AdoptGeoreference(const Georeference& georeference);
  const StoreOptions& options() const { return options_; }

  // ---- Versions and robots
  // The stored tiles are the map after every change up to this version.
  uint64_t checkpoint_version() const { return checkpoint_version_.load(); }
  // Highest version checkpointed or logged: a server continues with map_version() + 1.
  uint64_t map_version() const;
  std::optional<uint64_t> LastSequence(std::string_view robot_id) const {
    return log_->LastSequence(robot_id);
  }
  // Everything above, with the parameters, as one value (also what archives carry).
  MapMetadata Metadata() const;

  // ---- Tiles
  // The tile at `key` as of the last checkpoint; a null pointer if the store has no such tile.
  // DataLoss naming the key if the stored tile fails its checksum (the key is then listed by
  // CorruptTiles() and counted; other tiles are unaffected); IoError on a read failure.
  Result<std::unique_ptr<Tile>> LoadTile(TileKey key) const;

  // Atomically (one write, fsync'ed) stores `tiles`, records `version` as the checkpoint
  // version and deletes every log record at or below it.
  // Contract: the caller passes a consistent snapshot, i.e. the result of applying exactly the
  // changes with version <= `version` (and none above) to the map as of the previous
  // checkpoint, for every tile changed since that checkpoint. A server quiesces the changes
  // above `version` (or copies the tiles at a barrier) before calling. Tiles not passed keep
  // their stored state. InvalidArgument if `version` is below checkpoint_version(); IoError if
  // the write fails (the previous checkpoint and the log stay intact).
  // With retention (StoreOptions::retention) the checkpoint also keeps the tiles it replaces
  // (the history), becomes a base, and drops the log records, raw scans and history older than
  // the oldest base the retention bound keeps; without it, every record up to `version` goes.
  // `forget_earlier_bases`: the map changed outside the log (an import), so no earlier base
  // can be rebuilt from any more; this checkpoint becomes the only one.
  Status Checkpoint(uint64_t version, std::span<const TileUpdate> tiles,
                    bool forget_earlier_bases = false);

  // ---- Corrections (scan_history.h): retained checkpoints and rewriting the log
  // The retained checkpoints a rebuild may start from, ascending (empty without retention).
  // The log holds every record above the first one.
  std::vector<uint64_t> Bases() const;
  // The tiles at `keys` as they were at the retained checkpoint `base` (null: no tile then).
  // InvalidArgument if `base` is not in Bases(); DataLoss naming a corrupt stored tile.
  Result<std::vector<std::unique_ptr<Tile>>> LoadTilesAt(uint64_t base,
                                                         std::span<const TileKey> keys) const;
  // Atomically (one fsync'ed write): appends `correction` (a kCorrection record at a new
  // version), replaces the records in `rewritten` (same versions, their raw scans too),
  // deletes the records (and raw scans) in `removed`, and forgets the bases between
  // correction.base_version and correction.version, whose stored history predates it.
  Status ApplyCorrection(const LogRecord& correction, std::span<const LogRecord> rewritten,
                         std::span<const uint64_t> removed);

  // Every stored tile (from the index, no tile is read), in (x, y) order; or those with
  // min <= key <= max coordinate-wise.
  Result<std::vector<StoredTileInfo>> ListTiles() const;
  Result<std::vector<StoredTileInfo>> ListTiles(TileKey min, TileKey max) const;

  // A read-only view of the stored tiles as of now (tile_snapshot.h): later checkpoints do not
  // change what it lists or loads. Destroy it before the store; while one is open, Resume()
  // cannot reopen the database (it retries later).
  std::unique_ptr<TileSnapshot> NewSnapshot() const;

  // Tiles found corrupt since open and not rewritten since, sorted. Queries of these tiles
  // must not be answered from what the map holds for them.
  std::vector<TileKey> CorruptTiles() const;

  // ---- Log, maintenance, health
  ScanLog& log() { return *log_; }
  const ScanLog& log() const { return *log_; }

  // Writes memory tables to SST files (tests, measurement, before archiving a directory).
  Status Flush();
  // Flush() and a full compaction: the on-disk size settles to its steady value.
  Status Compact();
  // After a write failed (disk full, I/O error) every later write is refused with IoError, so
  // nothing half-written is ever acknowledged. Once the cause is gone (the disk has room),
  // Resume() brings the store back: RocksDB's own resume, or else a close and reopen of the
  // database in place. OK if writes are accepted again (OK at once if nothing failed).
  // A store opened read-only (full disk) is reopened for writing once the reserve is free
  // again. While less than the reserve is free, Resume() answers the reserve's IoError and
  // changes nothing: reopening would have RocksDB write onto a full disk.
  // Not thread-safe: call it with no other call on this store in flight.
  Status Resume();

  // Opened on a disk below the free-space reserve: every write is refused until Resume().
  bool read_only() const { return read_only_.load(); }
  // OK if `bytes` may be written next to the store now (the reserve stays free and the store
  // is writable); the refusal otherwise. For files the server keeps in the store's directory
  // (an import's spool); the store checks its own writes itself.
  Status AdmitWrite(uint64_t bytes) { return log_->AdmitWrite(bytes); }
  // Probes the free space now: OK if the reserve is free (whether or not the store is
  // read-only; Resume() reopens it).
  Status CheckFreeSpace() { return guard_->Check(); }
  // The reserve and the free space as last probed (reserve_bytes() 0: no reserve).
  const FreeSpaceGuard& free_space() const { return *guard_; }

  StoreCounters counters() const;
  DiskUsage Usage() const;

 private:
  TileStore(std::string dir, const StoreOptions& options, const MapParams& params,
            std::unique_ptr<StoreDb> db);
  static Result<std::unique_ptr<TileStore>> OpenImpl(const std::string& dir,
                                                     const StoreOptions& options,
                                                     const MapParams* params,
                                                     const Georeference& georeference);
  // Takes over an opened database: reads the versions and robots, starts the log.
  Status Attach(std::unique_ptr<StoreDb> db);
  void MarkCorrupt(TileKey key) const;
  // Retention at a checkpoint of `version`: the replaced tiles go to the history, the
  // bases are updated and what falls out of the bound is deleted (all into `batch`). Returns
  // the new bases. Requires checkpoint_mu_.
  // `dropped_through`: the log, raw scans and history at or below it are dropped (0: none).
  Result<std::vector<uint64_t>> AddRetention(rocksdb::WriteBatch* batch, uint64_t version,
                                             std::span<const TileUpdate> tiles,
                                             bool forget_earlier_bases, uint64_t* dropped_through);
  // Checkpoint() under checkpoint_mu_; sets `dropped_through` as AddRetention does.
  Status WriteCheckpoint(uint64_t version, std::span<const TileUpdate> tiles,
                         bool forget_earlier_bases, uint64_t* dropped_through);
  // Compacts the log, raw scans and history at or below `through`, which a checkpoint has
  // just range-deleted, so their files leave the disk now and not whenever RocksDB would
  // compact them. A failure is counted (StoreCounters::reclaim_errors), not returned.
  void ReclaimDropped(uint64_t through);
  // Compacts the tiles a checkpoint of `tiles` deleted (null or zero), when space is short.
  void ReclaimDeletedTiles(std::span<const TileUpdate> tiles);
  // Compacts the log, raw scans and history between versions `first` and `last` (inclusive).
  void CompactVersions(uint64_t first, uint64_t last);
  // RocksDB's estimate of the log, raw-scan and tile-history bytes above `version`.
  uint64_t RetainedBytesAbove(uint64_t version) const;
  // The stamp of the first scan record above `version`, and of the newest one (0: none).
  int64_t FirstStampAbove(uint64_t version) const;
  int64_t LastStamp() const;
  // LoadTile() and ListTiles() as of `snapshot` (null: now). A corrupt tile found through a
  // snapshot is not marked: a later checkpoint may have rewritten it.
  friend class TileSnapshot;
  Result<std::unique_ptr<Tile>> LoadTileAt(TileKey key, const rocksdb::Snapshot* snapshot) const;
  Result<std::vector<StoredTileInfo>> ListTilesAt(TileKey min, TileKey max,
                                                  const rocksdb::Snapshot* snapshot) const;

  std::string dir_;
  StoreOptions options_;
  MapParams params_;
  mutable std::mutex georeference_mu_;
  Georeference georeference_;              // guarded by georeference_mu_
  std::unique_ptr<FreeSpaceGuard> guard_;  // outlives log_, which checks it
  std::atomic<bool> read_only_{false};
  std::unique_ptr<StoreDb> db_;
  std::unique_ptr<ScanLog> log_;

  std::atomic<uint64_t> checkpoint_version_{0};
  std::mutex checkpoint_mu_;  // one checkpoint (or correction) at a time
  mutable std::mutex bases_mu_;
  std::vector<uint64_t> bases_;  // guarded by bases_mu_; written under checkpoint_mu_ too
  uint64_t bases_floor_ = 0;     // guarded by bases_mu_ (store_keys.h, kBasesFloorKey)
  mutable std::atomic<uint64_t> tiles_loaded_{0};
  std::atomic<uint64_t> tiles_written_{0}, tiles_deleted_{0}, checkpoints_{0};
  std::atomic<uint64_t> reclaims_{0}, reclaim_errors_{0};
  std::atomic<uint64_t> checkpoint_errors_{0};
  mutable std::mutex corrupt_mu_;
  mutable std::set<TileKey> corrupt_;  // until rewritten by a checkpoint
  mutable std::atomic<uint64_t> corrupt_found_{0};
  mutable std::atomic<int> open_snapshots_{0};
};

}  // namespace bgkmap::storage
