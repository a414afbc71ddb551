// Where the served map is made durable: one interface, two implementations, so the map-serving
// layer never asks whether there is a store.
//   - StoreDurability: the persistent store (storage/): scan log, stored tiles, checkpoints.
//   - MemoryDurability: a map in memory only; every call succeeds and stores nothing.
//
// The contract, in the order a change meets it:
//   1. Record() journals the change before it is applied (a refused change is not applied);
//   2. the change is applied in memory and its tiles are marked changed (Checkpointer);
//   3. a checkpoint captures the changed tiles at a scheduler barrier and WriteCheckpoint()
//      stores them, after which the log below that version may go.
// Tiles not in memory are read back through TileBacking (durability/tile_backing.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/storage/reintegration.h"
#include "bgkmap/storage/tile_store.h"
#include "durability/correction_plan.h"
#include "durability/tile_backing.h"

namespace bgkmap {

// A change about to be applied, as the journal sees it: a scan, or a clear of `clear_box`.
struct ChangeRecord {
  uint64_t version = 0;
  std::shared_ptr<const PreparedScan> scan;  // null for a clear
  std::string robot_id;
  uint64_t sequence = 0;
  CellBox clear_box;
  // The raw scan, kept beside the record when the store retains scans for corrections.
  std::shared_ptr<const RawScan> raw_scan;
};

// Copies of the served map's tiles, taken at a barrier (no change in flight).
class TileCopier {
 public:
  // Bitwise copies of the tiles at `keys` (null where the map has none).
  virtual std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const = 0;
  // Keys of the tiles in memory with min <= key <= max, sorted.
  virtual std::vector<TileKey> ListTiles(TileKey min, TileKey max) const = 0;

 protected:
  ~TileCopier() = default;
};

// The map's tiles as of one version, readable while the map changes on (an export).
class TileSource {
 public:
  virtual ~TileSource() = default;
  // The keys to read, sorted.
  virtual const std::vector<TileKey>& keys() const = 0;
  // The tile at keys()[i] (null: none); DataLoss naming a stored tile that fails its checksum.
  virtual Result<std::unique_ptr<Tile>> Take(size_t i) = 0;
};

// What Info and /metrics report of a persistent store.
struct StoreStatus {
  std::string directory;
  std::string durability;  // "sync" | "periodic"
  uint64_t checkpoint_version = 0;
  uint64_t corrupt_tiles = 0;
  bool write_failed = false;
  // Writes are refused for lack of space: below storage.min_free_space_mb, or opened read-only
  // on a full disk (then `read_only` too). Reads are served; writes resume when there is room.
  bool writes_paused_for_space = false;
  bool read_only = false;
  uint64_t free_bytes = 0;     // on the data dir's file system, as last probed
  uint64_t reserve_bytes = 0;  // storage.min_free_space_mb
  std::string paused_reason;   // why writes are paused ("" when they are not)
  storage::StoreCounters counters;
  storage::DiskUsage usage;  // only when asked for: it lists the store's directory
};

class Durability : public TileBacking {
 public:
  virtual ~Durability() = default;

  // True when tiles live outside memory too: then clean tiles may be evicted, a cleared tile is
  // kept (all zero) until a checkpoint deletes its stored copy, and checkpoints are worth taking.
  virtual bool persists() const = 0;

  // The state the map starts from: the version of its last change and each robot's last
  // logged sequence number.
  virtual uint64_t recovered_version() const = 0;
  virtual std::map<std::string, uint64_t> LoggedRobotSequences() const = 0;

  // ---- Pose corrections (docs/semantics.md, "Pose corrections"); a map in memory has none.
  // Whether Record() keeps raw scans (ChangeRecord::source) for corrections.
  virtual bool retains_scans() const { return false; }
  // Resolves a correction of `robot_id`'s scans against the log: its scans by sequence number,
  // each prepared again with its corrected pose in `poses` (or, with `remove`, the scans with
  // first <= sequence <= last dropped), and the retained checkpoint to rebuild from. InvalidArgument for a
  // pose the engine refuses; NotFound-like InvalidArgument for a sequence never logged;
  // FailedPrecondition when a scan is no longer retained (naming the robot's oldest retained
  // sequence number) or the map keeps none.
  virtual Result<CorrectionPlan> PlanCorrection(const std::string& robot_id,
                                                const std::map<uint64_t, Pose>& poses,
                                                const CorrectionRange& remove) const;
  // The re-integration of `plan` over the log's records below `end` (reintegration.h).
  virtual Result<storage::Reintegration> Reintegrate(const CorrectionPlan& plan, uint64_t end,
                                                     bool plan_only) const;
  // The map changed at `version` outside the log (an import): corrections cannot reach past it.
  virtual void NoteChangeOutsideLog(uint64_t /*version*/) {}
  // Journals the correction at `version` and rewrites the revised records, atomically and
  // durably: once OK, a restart rebuilds the corrected map.
  virtual Status RecordCorrection(const CorrectionPlan& plan, uint64_t version);

  // Forgets a robot's logged sequence number for good (it survives a restart as forgotten).
  // Called at a scheduler barrier: no scan of the robot is being journaled.
  virtual Status RetireRobot(const std::string& robot_id) = 0;

  // Journals a change before it is applied (durable as configured); not OK: skip the change.
  // Changes that do not conflict call it concurrently.
  virtual Status Record(const ChangeRecord& change) = 0;

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
  // Tiles the map holds newer than the store whose checkpoint was deferred at start (recovered
  // on a full disk): the first checkpoint after writes resume must write them.
  virtual std::vector<TileKey> DeferredTiles() const { return {}; }
  // OK if `bytes` more may be written to scratch_directory() (an import's spool) without eating
  // into the free-space reserve.
  virtual Status AdmitScratch(uint64_t /*bytes*/) { return Status::Ok(); }

  // At a barrier, right after a checkpoint at the applied version: the tiles in [min, max] as
  // of now, readable after the barrier ends. `map` supplies them where nothing is stored.
  virtual Result<std::unique_ptr<TileSource>> OpenTileSource(TileKey min, TileKey max,
                                                             const TileCopier& map) = 0;

  // Stored tiles found failing their checksum, sorted: queries must not answer from them.
  virtual std::vector<TileKey> CorruptTiles() const = 0;

  // Where an import spools its upload. `exclusive`: only this server writes there, so files a
  // crash left behind may be removed.
  struct ScratchDirectory {
    std::string path;
    bool exclusive = false;
  };
  virtual ScratchDirectory scratch_directory() const = 0;

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

  // The store's state for Info and /metrics; nullopt for a map in memory.
  virtual std::optional<StoreStatus> store_status(bool with_disk_usage) const = 0;

  // Where the map frame sits in a coordinate reference system (empty: a local frame): the
  // store's, which keeps the first one it is given (storage.md, "Georeference"), or for a map
  // in memory the configured one.
  virtual Georeference georeference() const = 0;
  // Ties a map in a local frame to `georeference` (an import of a georeferenced archive): OK at
  // once if it is empty or already the map's; FailedPrecondition naming the key if the map has
  // another; a store's write error otherwise.
  virtual Status AdoptGeoreference(const Georeference& georeference) = 0;
};

}  // namespace bgkmap
