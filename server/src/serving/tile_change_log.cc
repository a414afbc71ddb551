#include "serving/tile_change_log.h"

#include <algorithm>
#include <random>

namespace bgkmap {

TileChangeLog::TileChangeLog(uint64_t floor, uint64_t history_id)
    : floor_(floor), history_id_(history_id) {}

void TileChangeLog::History::Add(uint64_t v, const TileBlocks& b) {
  if (size > 0 && version[size - 1] >= v) {  // (the same change told again: one entry)
    blocks[size - 1] |= b;
    return;
  }
  if (size == kHistory) {  // the two oldest merge: their changes up to the newer version
    blocks[1] |= blocks[0];
    std::copy(version + 1, version + kHistory, version);
    std::copy(blocks + 1, blocks + kHistory, blocks);
    --size;
  }
  version[size] = v;
  blocks[size] = b;
  ++size;
}

TileBlocks TileChangeLog::History::BlocksAfter(uint64_t since) const {
  TileBlocks out;
  for (int i = size - 1; i >= 0 && version[i] > since; --i) out |= blocks[i];
  return out;
}

void TileChangeLog::Record(uint64_t version, const std::vector<TileKey>& tiles,
                           const std::vector<TileBlocks>& blocks) {
  std::lock_guard lock(mu_);
  for (size_t i = 0; i < tiles.size(); ++i) {
    changes_[tiles[i]].Add(version, blocks.empty() ? TileBlocks::All() : blocks[i]);
  }
}

std::optional<std::vector<ChangedTile>> TileChangeLog::ChangedSince(TileKey min, TileKey max,
                                                                    uint64_t since) const {
  if (since < floor_) return std::nullopt;
  std::vector<ChangedTile> out;
  std::lock_guard lock(mu_);
  // One ordered range per column of the box: (x, min.y) .. (x, max.y).
  for (auto it = changes_.lower_bound(min); it != changes_.end();) {
    const TileKey k = it->first;
    if (k.x > max.x) break;
    if (k.y < min.y) {
      it = changes_.lower_bound({k.x, min.y});
      continue;
    }
    if (k.y > max.y) {
      if (k.x == max.x) break;
      it = changes_.lower_bound({k.x + 1, min.y});
      continue;
    }
    if (it->second.last() > since) out.push_back({k, it->second.BlocksAfter(since)});
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
