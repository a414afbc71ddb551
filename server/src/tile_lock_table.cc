#include "tile_lock_table.h"

#include <algorithm>

namespace bgkmap {

TileLockTable::TileLockTable(size_t stripes)
    : count_(std::max<size_t>(stripes, 1)), stripes_(new std::shared_mutex[count_]) {}

TileLockTable::Guard& TileLockTable::Guard::operator=(Guard&& other) noexcept {
  if (this != &other) {
    Release();
    held_ = std::move(other.held_);
    other.held_.clear();
  }
  return *this;
}

void TileLockTable::Guard::Release() {
  // Reverse order of acquisition.
  for (auto it = held_.rbegin(); it != held_.rend(); ++it) {
    if (it->second) {
      it->first->unlock();
    } else {
      it->first->unlock_shared();
    }
  }
  held_.clear();
}

TileLockTable::Guard TileLockTable::Lock(std::span<const TileKey> exclusive,
                                         std::span<const TileKey> shared) {
  std::vector<std::pair<size_t, bool>> wanted;
  wanted.reserve(exclusive.size() + shared.size());
  for (TileKey k : exclusive) wanted.emplace_back(StripeOf(k), true);
  for (TileKey k : shared) wanted.emplace_back(StripeOf(k), false);
  return Acquire(std::move(wanted));
}

TileLockTable::Guard TileLockTable::LockRange(TileKey min, TileKey max) {
  std::vector<std::pair<size_t, bool>> wanted;
  const int64_t n = (int64_t{max.x} - min.x + 1) * (int64_t{max.y} - min.y + 1);
  if (n <= 0) return {};
  if (static_cast<uint64_t>(n) >= count_) return LockAll(false);  // every stripe anyway
  wanted.reserve(static_cast<size_t>(n));
  for (int y = min.y; y <= max.y; ++y) {
    for (int x = min.x; x <= max.x; ++x) wanted.emplace_back(StripeOf({x, y}), false);
  }
  return Acquire(std::move(wanted));
}

TileLockTable::Guard TileLockTable::LockAll(bool exclusive) {
  std::vector<std::pair<size_t, bool>> wanted;
  wanted.reserve(count_);
  for (size_t i = 0; i < count_; ++i) wanted.emplace_back(i, exclusive);
  return Acquire(std::move(wanted));
}

TileLockTable::Guard TileLockTable::Acquire(std::vector<std::pair<size_t, bool>> wanted) {
  // Sort by stripe, exclusive first, so the first entry of each stripe carries the strongest mode.
  std::sort(wanted.begin(), wanted.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second > b.second;
  });
  Guard guard;
  guard.held_.reserve(wanted.size());
  for (size_t i = 0; i < wanted.size(); ++i) {
    if (i > 0 && wanted[i].first == wanted[i - 1].first) continue;
    std::shared_mutex* m = &stripes_[wanted[i].first];
    if (wanted[i].second) {
      m->lock();
    } else {
      m->lock_shared();
    }
    guard.held_.emplace_back(m, wanted[i].second);
  }
  return guard;
}

}  // namespace bgkmap
