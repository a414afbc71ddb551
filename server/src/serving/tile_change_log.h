// The map version of each tile's last change since the server started: what a region delta
// (QueryRegion with since_version) answers from. A change is recorded before the applied
// version covers it, so a reader that read the applied version V first finds every change up
// to V here. Tiles a change emptied or removed stay recorded (the delta's tombstones).
//
// Kept in memory only: a since_version below the version the server started at (`floor`) is
// not answered from it. It holds one entry per tile changed since the start (24 bytes plus the
// tree's node), at most the tiles of the map plus those removed since.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

class TileChangeLog {
 public:
  // `floor`: the map version the server started at; `history_id`: names this record (random,
  // new at every start), so a since_version of another run is never taken for one of this one.
  TileChangeLog(uint64_t floor, uint64_t history_id);

  uint64_t floor() const { return floor_; }
  uint64_t history_id() const { return history_id_; }

  // Thread-safe. Changes of one tile are recorded in version order (the scheduler orders them).
  void Record(uint64_t version, const std::vector<TileKey>& tiles);

  // Sorted keys of the tiles with min <= key <= max (per axis) whose last change is after
  // `since`; nullopt if `since` < floor() (changes before the start are not known here).
  std::optional<std::vector<TileKey>> ChangedSince(TileKey min, TileKey max, uint64_t since) const;

 private:
  const uint64_t floor_;
  const uint64_t history_id_;
  mutable std::mutex mu_;
  std::map<TileKey, uint64_t> last_change_;  // sorted by (x, y): a column is one range
};

// A random, non-zero history id.
uint64_t NewHistoryId();

}  // namespace bgkmap
