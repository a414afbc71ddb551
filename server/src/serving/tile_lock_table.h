// Reader/writer exclusion between map readers (queries) and changes, per tile. Ordering between
// changes is ScanScheduler's job; these locks only make each change atomic for readers: a reader
// holds the tiles it reads shared for the whole read, a scan holds the tiles it writes exclusive
// for the whole integration.
//
// One lock per tile key, so scans of disjoint tiles never contend. Entries exist only while
// someone holds or waits for them, so memory is bounded by the operations in flight, not by the
// keys ever queried.
#pragma once

#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

class TileLockTable {
 private:
  struct Entry {
    std::shared_mutex mu;
    int users = 0;  // holders and waiters; guarded by TileLockTable::mu_
  };

 public:
  // Releases its locks on destruction.
  class Guard {
   public:
    Guard() = default;
    Guard(Guard&& other) noexcept;
    Guard& operator=(Guard&& other) noexcept;
    Guard(const Guard&) = delete;
    Guard& operator=(const Guard&) = delete;
    ~Guard() { Release(); }
    void Release();

   private:
    friend class TileLockTable;
    struct Held {
      TileKey key;
      Entry* entry;
      bool exclusive;
    };
    TileLockTable* table_ = nullptr;
    std::vector<Held> held_;
  };

  // Locks `exclusive` tiles exclusively and `shared` tiles shared (a key in both is exclusive).
  // Tiles are locked in ascending key order, so any two callers are deadlock-free.
  Guard Lock(std::span<const TileKey> exclusive, std::span<const TileKey> shared);
  // Every key of the inclusive rectangle [min, max], shared.
  Guard LockRange(TileKey min, TileKey max);
  // `keys` (sorted, unique) shared if none of them is held exclusively right now;
  // otherwise nothing is held and the result is empty. Never blocks on a tile lock: for a reader
  // that would rather hand its work to another thread than wait on this one.
  std::optional<Guard> TryLockShared(std::span<const TileKey> keys);

  size_t entry_count() const;

 private:
  // A guard naming `wanted` (ascending keys, the strongest mode of a key first; later entries of
  // a key are skipped), each entry counted as used, none of them locked yet.
  Guard Register(std::span<const std::pair<TileKey, bool>> wanted);
  void Unref(const std::vector<Guard::Held>& held);

  mutable std::mutex mu_;
  std::unordered_map<TileKey, std::unique_ptr<Entry>, TileKeyHash> entries_;
};

}  // namespace bgkmap
