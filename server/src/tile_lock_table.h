// Reader/writer exclusion between map readers (queries) and scan integration, per tile.
// Ordering between scans is ScanScheduler's job; these locks only make each scan atomic for
// readers: a reader holds its tiles shared for the whole read, a scan holds its write tiles
// exclusive (and read tiles shared) for the whole integration.
#pragma once

#include <cstddef>
#include <memory>
#include <shared_mutex>
#include <span>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

class TileLockTable {
 public:
  // Tiles hash onto `stripes` locks; two tiles sharing a stripe only cost some parallelism.
  explicit TileLockTable(size_t stripes = 1024);

  // Releases its locks on destruction.
  class Guard {
   public:
    Guard() = default;
    Guard(Guard&& other) noexcept : held_(std::move(other.held_)) { other.held_.clear(); }
    Guard& operator=(Guard&& other) noexcept;
    Guard(const Guard&) = delete;
    Guard& operator=(const Guard&) = delete;
    ~Guard() { Release(); }
    void Release();

   private:
    friend class TileLockTable;
    std::vector<std::pair<std::shared_mutex*, bool>> held_;  // (lock, exclusive)
  };

  // Locks the stripes of `exclusive` tiles exclusively and of `shared` tiles shared. Stripes are
  // taken in ascending order, so any two callers are deadlock-free.
  Guard Lock(std::span<const TileKey> exclusive, std::span<const TileKey> shared);
  // Every tile of the inclusive key rectangle [min, max], shared.
  Guard LockRange(TileKey min, TileKey max);
  // Every stripe: the whole map (Info, ClearRegion).
  Guard LockAll(bool exclusive);

 private:
  size_t StripeOf(TileKey key) const { return TileKeyHash{}(key) % count_; }
  Guard Acquire(std::vector<std::pair<size_t, bool>> wanted);

  size_t count_;
  std::unique_ptr<std::shared_mutex[]> stripes_;
};

}  // namespace bgkmap
