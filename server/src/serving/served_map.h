// The served map: the single server's implementation of the map port (serving/map_port.h), and
// the only way to its tiles. No gRPC here.
//
// It owns the transactions and the rules every caller would otherwise repeat:
//   - changes (scans, clears, imports) are ordered by ChangeScheduler, pin their tiles, are
//     journaled by the Durability before they are applied, mark their tiles for the next
//     checkpoint, and update the map summary as one step;
//   - export snapshots and checkpoints run at scheduler barriers through the Checkpointer;
//   - reads pin and lock what they read, see whole changes only, and never answer from a tile
//     the store found corrupt (DataLoss naming it);
//   - counts and bounds are kept per tile (MapSummaryIndex): a change marks its tiles, and
//     Summary() recounts only those, never locking or walking the whole map.
#pragma once

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "durability/checkpointer.h"
#include "durability/durability.h"
#include "serving/change_scheduler.h"
#include "serving/idle_scratch_release.h"
#include "serving/map_port.h"
#include "serving/map_summary.h"
#include "serving/map_writes.h"
#include "serving/robot_registry.h"
#include "serving/table_copies.h"
#include "serving/tile_change_log.h"
#include "serving/tile_residency.h"
#include "serving/tile_table.h"

namespace bgkmap {

// The map's tiles in a key range as of one version, readable while ingestion goes on.
struct MapSnapshot {
  uint64_t version = 0;
  std::map<std::string, uint64_t> robot_sequences;  // as logged up to `version` (store only)
  std::unique_ptr<TilesAtVersion> tiles;
};

struct ServedMapOptions {
  uint32_t max_robots = 0;
  uint64_t max_sequence_jump = 0;        // 0: no limit (RobotSequenceRule)
  uint64_t tile_memory_limit_bytes = 0;  // 0: unbounded
  // Dense tiles beyond this are packed, least recently used first (storage.dense_tiles_mb;
  // 0: never packed).
  uint64_t dense_tile_limit_bytes = 0;
  // Tiles used more recently than this are not packed (TileResidency).
  std::chrono::milliseconds pack_after_idle = std::chrono::seconds(1);
  // Called (from a worker, without locks held) when tiles in memory exceed the limit, or the
  // dense ones theirs.
  std::function<void()> on_over_memory;
  // Called on a worker after each change with the tiles it changed (watchers).
  ChangeScheduler::TilesChanged on_tiles_changed;
  // The workers' count, and how long after the last change their engine scratch is handed back
  // (IdleScratchRelease).
  size_t worker_threads = 1;
  std::chrono::milliseconds scratch_idle = std::chrono::seconds(2);
  // A large scan's integration in up to this many bands on the workers, each of at least
  // scan_band_cells observed cells (ScanBandOptions; 1: whole scans only).
  int scan_bands = 1;
  size_t scan_band_cells = ScanBandOptions{}.cells_per_band;
};

class ServedMap final : public MapPort {
 public:
  // `map` holds what the durability recovered; `durability` outlives the served map.
  ServedMap(std::unique_ptr<TerrainMap> map, Durability& durability,
            boost::asio::thread_pool& workers, ServedMapOptions options);
  ~ServedMap();  // waits for admitted changes

  const MapParams& params() const override { return table_.params(); }
  const GridGeometry& geometry() const override { return table_.geometry(); }

  // ---- MapWrites. Each `done` runs on a worker once the change counts as applied (or was
  // refused).
  using Admission = RobotAdmission;
  Status Offers(Operation) const override { return Status::Ok(); }
  bool retains_scans() const override { return durability_.retains_scans(); }
  uint64_t retained_records_bound() const override { return durability_.retained_records_bound(); }
  bool TakeDuplicate(const std::string& robot_id, uint64_t sequence, uint64_t* last) override;
  void CountRejected(const std::string& robot_id) override { robots_.CountRejected(robot_id); }
  Admission SubmitScan(ScanOrigin origin, std::shared_ptr<const PreparedScan> scan,
                       std::function<void(ScanOutcome)> done,
                       uint64_t* last_sequence = nullptr) override;
  void SubmitClear(const CellBox& box, std::function<void(ClearOutcome)> done) override;
  // Spools to the durability's scratch directory, within its free-space reserve; the checked
  // archive is added by SubmitImport().
  Result<std::unique_ptr<ArchiveUpload>> BeginImport() override;
  // An archive written from SubmitSnapshot(): a checkpoint at a barrier, then the store's
  // snapshot (or copies of the tiles for a map in memory).
  void SubmitExport(const std::optional<CellBox>& box,
                    std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) override;
  // Re-integrates a robot's scans with corrected poses, or without the removed ones, so that the
  // map equals the one built from scratch with them (docs/semantics.md, "Pose corrections").
  // Runs in the background: queries go on answering from the map as it is, scans into other
  // tiles go on integrating, and scans into the corrected region wait; the corrected tiles then
  // switch in as one change at the correction's version (told to watchers).
  void SubmitCorrection(CorrectionSpec spec, std::function<void(CorrectionOutcome)> done) override;
  // Scans admitted after this call see the robot as new (its next scan starts a new sequence,
  // and it no longer counts against max_robots); at the next barrier the store forgets it too.
  void RetireRobot(const std::string& robot_id,
                   std::function<void(Result<RobotStats>)> done) override;

  // Adds the tiles' statistics (a merge) as one exclusive change, checkpointed at once: if that
  // fails the tiles are put back and the outcome is IoError; a stored tile that fails its
  // checksum is DataLoss; a sum that would not be finite (overflow) is OutOfRange naming the
  // tile and cell, and nothing is added. `keys` (sorted, distinct) and `tiles` must outlive `done`.
  void SubmitImport(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles,
                    std::function<void(ImportOutcome)> done);
  // At a barrier, checkpoints the map and opens its tiles in [min, max] as of that version.
  void SubmitSnapshot(TileKey min, TileKey max, std::function<void(Result<MapSnapshot>)> done);
  // Captures the changed tiles at a barrier and writes them outside it.
  Status Checkpoint();
  CorrectionStats corrections() const;

  // ---- MapReads: IoError if the store cannot be read, DataLoss naming a corrupt tile.
  uint64_t applied_version() const override { return scheduler_.applied_version(); }
  Result<Raster> ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                            int stride) override;
  Result<std::vector<CellEstimate>> ReadCells(std::span<const CellIndex> cells) override;
  std::optional<Result<std::vector<CellEstimate>>> TryReadCellsNow(
      std::span<const CellIndex> cells) override;
  Result<TileContent> ReadTile(TileKey key, const std::vector<Layer>& layers) override;
  // Keys of the tiles with min <= key <= max, in memory or stored, sorted.
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const;
  Result<std::vector<TileKey>> ListKnownTiles(TileKey min, TileKey max) override {
    return ListTiles(min, max);
  }
  uint64_t history_id() const override { return change_log_.history_id(); }
  // From the change log kept since the start: a `since` below the version the server started
  // at (the log is not stored) is FailedPrecondition.
  Result<std::vector<ChangedTile>> TilesChangedSince(TileKey min, TileKey max,
                                                     uint64_t since) override;

  // ---- What Info and /metrics report.
  uint64_t known_version() const override { return applied_version(); }
  std::vector<RobotStats> Robots() const override { return robots_.Robots(); }
  MapState State(bool with_disk_usage = false) override;
  void ReadVersion(std::function<void(uint64_t)> done) override { done(applied_version()); }
  MapSummary Summary();
  // The store's state; nullopt for a map in memory.
  std::optional<StoreStatus> store_status(bool with_disk_usage = false) const {
    return durability_.store_status(with_disk_usage);
  }
  uint64_t scans_applied() const { return scans_applied_.load(); }
  RobotRegistry& robots() { return robots_; }
  const RobotRegistry& robots() const { return robots_; }

  // Memory.
  uint64_t Evict(uint64_t target_bytes) { return residency_.Evict(target_bytes); }
  ResidencyStats Residency() const { return residency_.Stats(); }
  uint64_t TileBytes() const { return table_.TileBytes(); }
  Checkpointer& checkpointer() { return checkpointer_; }
  const Checkpointer& checkpointer() const { return checkpointer_; }
  uint32_t peak_parallel_integrations() const { return table_.peak_parallel_integrations(); }
  // Scans integrated in bands (ServedMapOptions::scan_bands).
  uint64_t banded_scans() const { return table_.banded_scans(); }

  // Blocks until every admitted change has finished.
  void WaitIdle() { scheduler_.WaitIdle(); }
  // Shutting down: no scratch release is left pending on the workers, whose pool can then be
  // joined at once (not when the release's idle time has passed).
  void StopScratchRelease() { scratch_release_.Stop(); }
  // For tests and reports: a copy of every tile, stored ones included.
  std::unique_ptr<TerrainMap> Snapshot() const;

 private:
  ChangeScheduler::Done RunScan(const ScanOrigin& origin, std::shared_ptr<const PreparedScan> scan,
                                uint64_t previous_sequence, uint64_t version,
                                std::function<void(ScanOutcome)> done);
  struct CorrectionJob;
  void ScheduleCorrection(std::shared_ptr<CorrectionJob> job, std::vector<TileKey> region);
  ChangeScheduler::Done RunCorrection(std::shared_ptr<CorrectionJob> job,
                                      const std::vector<TileKey>& region, uint64_t version);
  ChangeScheduler::Done RunClear(const CellBox& box, uint64_t version,
                                 std::function<void(ClearOutcome)> done);
  ChangeScheduler::Done RunImport(std::span<const TileKey> keys,
                                  std::span<const std::unique_ptr<Tile>> tiles, uint64_t version,
                                  std::function<void(ImportOutcome)> done);
  // DataLoss naming the first tile of the range (or of `keys`) the store found corrupt.
  Status RefuseCorrupt(TileKey min, TileKey max) const;
  Status RefuseCorrupt(std::span<const TileKey> keys) const;
  // The tiles of `cells`, sorted and unique.
  std::vector<TileKey> TilesOf(std::span<const CellIndex> cells) const;

  Durability& durability_;
  TileTable table_;
  TableCopies copies_{table_};
  TileResidency residency_;
  Checkpointer checkpointer_;
  MapSummaryIndex summary_;
  RobotRegistry robots_;
  std::mutex admission_mu_;  // a robot's sequence order is its version order
  std::atomic<uint64_t> scans_applied_{0};
  mutable std::mutex corrections_mu_;
  CorrectionStats corrections_;
  TileChangeLog change_log_;
  IdleScratchRelease scratch_release_;
  ChangeScheduler scheduler_;  // last: its workers use everything above
};

}  // namespace bgkmap
