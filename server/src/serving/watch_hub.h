// Fan-out of changed tiles to Watch subscribers.
//
// Slow watchers must not slow ingestion, and memory must stay bounded, so updates are coalesced
// per tile: each subscriber has a set of pending tile keys (at most the tiles of its region).
// Publishing only inserts keys and wakes the subscriber; the subscriber reads a tile's content
// when it is ready to send it, so one update carries every change made to the tile since the
// previous update. Every change is delivered, merged with later ones if the watcher is slow.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <set>
#include <unordered_map>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

class WatchHub {
 public:
  using Wake = std::function<void()>;

  // Watches tiles in [min, max]. `wake` is called (with the hub's lock held: it must only
  // schedule work) whenever published keys become pending. `initial` keys start pending without
  // a wake: the subscriber starts its first cycle itself once it knows its id.
  uint64_t Subscribe(TileKey min, TileKey max, Wake wake, const std::vector<TileKey>& initial);
  // After this returns, `wake` of `id` is never called again.
  void Unsubscribe(uint64_t id);

  // Makes `keys` pending for `id` alone, without a wake (its own cycle takes them).
  void AddPending(uint64_t id, const std::vector<TileKey>& keys);

  void Publish(const std::vector<TileKey>& changed);
  // Every tile in [min, max] changed (or may have): what a cluster's log tells each node.
  void PublishBox(TileKey min, TileKey max);

  // The next pending tile of `id` (smallest key first), removing it; false if none.
  bool Take(uint64_t id, TileKey* key);

  size_t subscriber_count() const;

 private:
  struct Subscriber {
    TileKey min, max;
    Wake wake;
    std::set<TileKey> pending;
  };
  mutable std::mutex mu_;
  uint64_t next_id_ = 1;
  std::unordered_map<uint64_t, Subscriber> subscribers_;
};

}  // namespace bgkmap
