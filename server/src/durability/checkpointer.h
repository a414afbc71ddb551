// The one owner of the checkpoint contract, used alike by periodic checkpoints, eviction,
// import, export and shutdown:
//   - every applied change marks the tiles it changed (MarkChanged);
//   - Capture(), at a scheduler barrier (no change in flight, every change up to `version` in
//     the map), first resumes a store whose last write failed, then copies the changed tiles;
//   - Write() stores the copies, outside the barrier or inside it; if it fails, the tiles stay
//     marked for the next checkpoint (the scan log still holds their changes).
// Checkpoints are written in the order they were captured: a later one must not land first and
// drop log records that an earlier, still unwritten one has not stored yet.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <semaphore>
#include <set>
#include <span>
#include <vector>

#include "durability/checkpoint_store.h"

namespace bgkmap {

// Tiles copied at a barrier, ready to be written.
struct CapturedCheckpoint {
  uint64_t version = 0;
  std::vector<TileKey> keys;
  std::vector<std::unique_ptr<Tile>> tiles;  // null: the tile is gone (cleared)
  // Held from Capture() to the end of Write() (possibly on another thread, hence a semaphore).
  std::shared_ptr<std::binary_semaphore> order;
};

class Checkpointer {
 public:
  // `persists`: the store keeps tiles (else nothing is ever written and no tile is marked).
  Checkpointer(CheckpointStore& store, bool persists, const ResidentTiles& map)
      : store_(store), persists_(persists), map_(map) {}

  // After a change was applied: every tile it may have changed. Calls the dirty-limit callback
  // (without locks held) when more tiles than the limit are changed since the last capture.
  void MarkChanged(std::span<const TileKey> tiles);
  // Under a memory bound, checkpoints must come often enough that their copies stay small.
  // Call before any change is applied; 0: no limit.
  void SetDirtyLimit(size_t tiles, std::function<void()> on_over_limit);
  bool dirty_over_limit() const;
  size_t dirty_tiles() const;

  // At a barrier. Waits while an earlier capture is not written yet; the result must be passed
  // to Write() (or dropped) promptly.
  CapturedCheckpoint Capture(uint64_t version);
  Status Write(CapturedCheckpoint captured);
  // Both, inside a barrier (an import or an export that needs the store to hold the map).
  Status CheckpointAt(uint64_t version) { return Write(Capture(version)); }

 private:
  CheckpointStore& store_;
  const bool persists_;
  const ResidentTiles& map_;
  std::shared_ptr<std::binary_semaphore> order_ = std::make_shared<std::binary_semaphore>(1);
  mutable std::mutex dirty_mu_;
  std::set<TileKey> dirty_;  // changed since the last capture
  size_t dirty_limit_ = 0;   // 0: none
  std::function<void()> on_dirty_over_limit_;
};

}  // namespace bgkmap
