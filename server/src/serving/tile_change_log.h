// The map version of each tile's last change since the server started: what a region delta
// (QueryRegion with since_version) answers from. A change is recorded before the applied
// version covers it, so a reader that read the applied version V first finds every change up
// to V here. Tiles a change emptied or removed stay recorded (the delta's tombstones).
//
// Per tile it also keeps which blocks (tile_blocks.h) changed, as a short history of (version,
// blocks) entries: when the history is full its two oldest entries merge (the newer version,
// both masks), so a delta since a recent version names the blocks changed since, and one since
// an older version may name more (never fewer).
//
// Kept in memory only: a since_version below the version the server started at (`floor`) is
// not answered from it. It holds one entry per tile changed since the start (~250 bytes plus
// the tree's node), at most the tiles of the map plus those removed since.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile_blocks.h"

namespace bgkmap {

class TileChangeLog {
 public:
  // `floor`: the map version the server started at; `history_id`: names this record (random,
  // new at every start), so a since_version of another run is never taken for one of this one.
  TileChangeLog(uint64_t floor, uint64_t history_id);

  uint64_t floor() const { return floor_; }
  uint64_t history_id() const { return history_id_; }

  // Thread-safe. Changes of one tile are recorded in version order (the scheduler orders them).
  // blocks[i]: the blocks of tiles[i] the change may have changed; empty: whole tiles.
  void Record(uint64_t version, const std::vector<TileKey>& tiles,
              const std::vector<TileBlocks>& blocks = {});

  // The tiles with min <= key <= max (per axis) whose last change is after `since`, sorted by
  // key, with the blocks changed after it (a superset); nullopt if `since` < floor() (changes
  // before the start are not known here).
  std::optional<std::vector<ChangedTile>> ChangedSince(TileKey min, TileKey max,
                                                       uint64_t since) const;

  // Entries of block history kept per tile.
  static constexpr int kHistory = 6;

 private:
  const uint64_t floor_;
  const uint64_t history_id_;
  // A tile's changes, oldest first: entry i covers the changes after entry i - 1's version up to
  // its own (the first: since the start).
  struct History {
    uint64_t version[kHistory] = {};
    TileBlocks blocks[kHistory] = {};
    int size = 0;
    uint64_t last() const { return version[size - 1]; }
    void Add(uint64_t v, const TileBlocks& b);
    TileBlocks BlocksAfter(uint64_t since) const;
  };
  mutable std::mutex mu_;
  std::map<TileKey, History> changes_;  // sorted by (x, y): a column is one range
};

// A random, non-zero history id.
uint64_t NewHistoryId();

}  // namespace bgkmap
