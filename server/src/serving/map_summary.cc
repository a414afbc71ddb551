#include "serving/map_summary.h"

#include <algorithm>

namespace bgkmap {
namespace {

bool Inside(const CellBox& inner, const CellBox& outer) {
  return inner.empty() || (outer.Contains(inner.min) && outer.Contains(inner.max));
}

}  // namespace

void MapSummaryIndex::Update(std::span<const TileKey> keys,
                             std::span<const TileSummary> summaries) {
  std::lock_guard lock(mu_);
  bool shrank = false;
  for (size_t i = 0; i < keys.size(); ++i) {
    const TileSummary& now = summaries[i];
    auto it = tiles_.find(keys[i]);
    if (it != tiles_.end()) {
      known_cells_ -= it->second.known_cells;
      // A box that loses ground may have held the map's edge.
      shrank |= !Inside(it->second.known_box, now.known_box);
    }
    if (now.known_cells == 0) {
      if (it != tiles_.end()) tiles_.erase(it);
      continue;
    }
    known_cells_ += now.known_cells;
    if (it != tiles_.end()) {
      it->second = now;
    } else {
      tiles_.emplace(keys[i], now);
    }
    bounds_.Extend(now.known_box.min);
    bounds_.Extend(now.known_box.max);
  }
  if (shrank) RecomputeBounds();
}

void MapSummaryIndex::RecomputeBounds() {
  bounds_ = CellBox{};
  for (const auto& [_, t] : tiles_) {
    bounds_.Extend(t.known_box.min);
    bounds_.Extend(t.known_box.max);
  }
}

void MapSummaryIndex::MarkStale(std::span<const TileKey> keys) {
  std::lock_guard lock(mu_);
  stale_.insert(keys.begin(), keys.end());
}

MapSummary MapSummaryIndex::Get(const Recount& recount) {
  std::lock_guard one(recount_mu_);
  std::vector<TileKey> keys;
  {
    std::lock_guard lock(mu_);
    keys.assign(stale_.begin(), stale_.end());
    stale_.clear();
  }
  if (!keys.empty()) {
    // A key marked again meanwhile stays stale and is recounted by the next read.
    std::sort(keys.begin(), keys.end());
    const std::vector<TileSummary> now = recount(keys);
    Update(keys, now);
  }
  std::lock_guard lock(mu_);
  return {tiles_.size(), known_cells_, bounds_};
}

}  // namespace bgkmap
