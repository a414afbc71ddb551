#include "serving/watch_hub.h"

#include <algorithm>

namespace bgkmap {

uint64_t WatchHub::Subscribe(TileKey min, TileKey max, Wake wake,
                             const std::vector<TileKey>& initial) {
  std::lock_guard lock(mu_);
  const uint64_t id = next_id_++;
  Subscriber& s = subscribers_[id];
  s.min = min;
  s.max = max;
  s.wake = std::move(wake);
  s.pending.insert(initial.begin(), initial.end());
  return id;
}

void WatchHub::Unsubscribe(uint64_t id) {
  std::lock_guard lock(mu_);
  subscribers_.erase(id);
}

void WatchHub::AddPending(uint64_t id, const std::vector<TileKey>& keys) {
  std::lock_guard lock(mu_);
  auto it = subscribers_.find(id);
  if (it != subscribers_.end()) it->second.pending.insert(keys.begin(), keys.end());
}

void WatchHub::Publish(const std::vector<TileKey>& changed) {
  std::lock_guard lock(mu_);
  for (auto& [id, s] : subscribers_) {
    bool added = false;
    for (TileKey k : changed) {
      if (k.x < s.min.x || k.x > s.max.x || k.y < s.min.y || k.y > s.max.y) continue;
      added |= s.pending.insert(k).second;
    }
    if (added) s.wake();
  }
}

void WatchHub::PublishBox(TileKey min, TileKey max) {
  std::lock_guard lock(mu_);
  for (auto& [id, s] : subscribers_) {
    // The part of the box the subscriber watches: at most its own tiles.
    const int x0 = std::max(min.x, s.min.x), x1 = std::min(max.x, s.max.x);
    const int y0 = std::max(min.y, s.min.y), y1 = std::min(max.y, s.max.y);
    bool added = false;
    for (int x = x0; x <= x1; ++x) {
      for (int y = y0; y <= y1; ++y) added |= s.pending.insert({x, y}).second;
    }
    if (added) s.wake();
  }
}

bool WatchHub::Take(uint64_t id, TileKey* key) {
  std::lock_guard lock(mu_);
  auto it = subscribers_.find(id);
  if (it == subscribers_.end() || it->second.pending.empty()) return false;
  *key = *it->second.pending.begin();
  it->second.pending.erase(it->second.pending.begin());
  return true;
}

size_t WatchHub::subscriber_count() const {
  std::lock_guard lock(mu_);
  return subscribers_.size();
}

}  // namespace bgkmap
