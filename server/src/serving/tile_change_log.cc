#include "serving/tile_change_log.h"

#include <algorithm>
#include <random>

namespace bgkmap {

TileChangeLog::TileChangeLog(uint64_t floor, uint64_t history_id)
    : floor_(floor), history_id_(history_id) {}

void TileChangeLog::Record(uint64_t version, const std::vector<TileKey>& tiles) {
  std::lock_guard lock(mu_);
  for (TileKey k : tiles) {
    uint64_t& last = last_change_[k];
    last = std::max(last, version);
  }
}

std::optional<std::vector<TileKey>> TileChangeLog::ChangedSince(TileKey min, TileKey max,
                                                                uint64_t since) const {
  if (since < floor_) return std::nullopt;
  std::vector<TileKey> out;
  std::lock_guard lock(mu_);
  // One ordered range per column of the box: (x, min.y) .. (x, max.y).
  for (auto it = last_change_.lower_bound(min); it != last_change_.end();) {
    const TileKey k = it->first;
    if (k.x > max.x) break;
    if (k.y < min.y) {
      it = last_change_.lower_bound({k.x, min.y});
      continue;
    }
    if (k.y > max.y) {
      if (k.x == max.x) break;
      it = last_change_.lower_bound({k.x + 1, min.y});
      continue;
    }
    if (it->second > since) out.push_back(k);
    ++it;
  }
  return out;
}

uint64_t NewHistoryId() {
  std::random_device device;
  std::mt19937_64 bits((static_cast<uint64_t>(device()) << 32) ^ device());
  uint64_t id = 0;
  while (id == 0) id = bits();
  return id;
}

}  // namespace bgkmap
