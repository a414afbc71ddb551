// Where the served map is made durable, as small interfaces by concern, so that each part of
// the serving layer takes only what it uses:
//   - Journal (journal.h): changes recorded before they are applied;
//   - CheckpointStore (checkpoint_store.h): changed tiles stored, and export sources;
//   - StoredTiles (stored_tiles.h): tiles not in memory, loaded on demand, checked;
//   - CorrectionLog (correction_log.h): retained scans and pose corrections;
//   - MapFrame (map_frame.h): the georeference;
//   - ScratchSpace (scratch_space.h): where an import spools.
// Durability is all of them, with two implementations, so the serving layer never asks whether
// there is a store:
//   - StoreDurability: the persistent store (storage/): scan log, stored tiles, checkpoints.
//   - MemoryDurability: a map in memory only; every call succeeds and stores nothing.
// tests/server/durability/durability_contract_test.cc runs the contract against both.
//
// The contract, in the order a change meets it:
//   1. Journal::Record() journals the change before it is applied (a refused change is not
//      applied);
//   2. the change is applied in memory and its tiles are marked changed (Checkpointer);
//   3. a checkpoint captures the changed tiles at a scheduler barrier and
//      CheckpointStore::WriteCheckpoint() stores them, after which the log below that version
//      may go.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "bgkmap/storage/tile_store.h"
#include "durability/checkpoint_store.h"
#include "durability/correction_log.h"
#include "durability/journal.h"
#include "durability/map_frame.h"
#include "durability/scratch_space.h"
#include "durability/stored_tiles.h"

namespace bgkmap {

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

class Durability : public Journal,
                   public CheckpointStore,
                   public StoredTiles,
                   public CorrectionLog,
                   public MapFrame,
                   public ScratchSpace {
 public:
  virtual ~Durability() = default;

  // True when tiles live outside memory too: then clean tiles may be evicted, a cleared tile is
  // kept (all zero) until a checkpoint deletes its stored copy, and checkpoints are worth taking.
  virtual bool persists() const = 0;
  // The store's state for Info and /metrics; nullopt for a map in memory.
  virtual std::optional<StoreStatus> store_status(bool with_disk_usage) const = 0;
};

}  // namespace bgkmap
