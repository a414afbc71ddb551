#include "serving/tile_lock_table.h"

#include <algorithm>

namespace bgkmap {

TileLockTable::Guard::Guard(Guard&& other) noexcept
    : table_(other.table_), held_(std::move(other.held_)) {
  other.held_.clear();
}

TileLockTable::Guard& TileLockTable::Guard::operator=(Guard&& other) noexcept {
  if (this != &other) {
    Release();
    table_ = other.table_;
    held_ = std::move(other.held_);
    other.held_.clear();
  }
  return *this;
}

void TileLockTable::Guard::Release() {
  if (held_.empty()) return;
  for (auto it = held_.rbegin(); it != held_.rend(); ++it) {
    if (it->exclusive) {
      it->entry->mu.unlock();
    } else {
      it->entry->mu.unlock_shared();
    }
  }
  table_->Unref(held_);
  held_.clear();
}

TileLockTable::Guard TileLockTable::Lock(std::span<const TileKey> exclusive,
                                         std::span<const TileKey> shared) {
  std::vector<std::pair<TileKey, bool>> wanted;
  wanted.reserve(exclusive.size() + shared.size());
  for (TileKey k : exclusive) wanted.emplace_back(k, true);
  for (TileKey k : shared) wanted.emplace_back(k, false);
  // Ascending keys, exclusive first, so the first entry of a key carries the strongest mode.
  std::sort(wanted.begin(), wanted.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second > b.second;
  });
  Guard guard = Register(wanted);
  for (const Guard::Held& h : guard.held_) {
    if (h.exclusive) {
      h.entry->mu.lock();
    } else {
      h.entry->mu.lock_shared();
    }
  }
  return guard;
}

TileLockTable::Guard TileLockTable::LockRange(TileKey min, TileKey max) {
  std::vector<TileKey> keys;
  if (min.x <= max.x && min.y <= max.y) {
    keys.reserve(static_cast<size_t>(int64_t{max.x} - min.x + 1) *
                 static_cast<size_t>(int64_t{max.y} - min.y + 1));
    for (int x = min.x; x <= max.x; ++x) {
      for (int y = min.y; y <= max.y; ++y) keys.push_back({x, y});
    }
  }
  return Lock({}, keys);
}

std::optional<TileLockTable::Guard> TileLockTable::TryLockShared(std::span<const TileKey> keys) {
  std::vector<std::pair<TileKey, bool>> wanted;
  wanted.reserve(keys.size());
  for (TileKey k : keys) wanted.emplace_back(k, false);
  Guard guard = Register(wanted);
  for (size_t i = 0; i < guard.held_.size(); ++i) {
    if (guard.held_[i].entry->mu.try_lock_shared()) continue;
    for (size_t j = 0; j < i; ++j) guard.held_[j].entry->mu.unlock_shared();
    Unref(guard.held_);
    guard.held_.clear();
    return std::nullopt;
  }
  return guard;
}

TileLockTable::Guard TileLockTable::Register(std::span<const std::pair<TileKey, bool>> wanted) {
  Guard guard;
  guard.table_ = this;
  guard.held_.reserve(wanted.size());
  std::lock_guard lock(mu_);
  for (size_t i = 0; i < wanted.size(); ++i) {
    if (i > 0 && wanted[i].first == wanted[i - 1].first) continue;
    std::unique_ptr<Entry>& e = entries_[wanted[i].first];
    if (!e) e = std::make_unique<Entry>();
    ++e->users;
    guard.held_.push_back({wanted[i].first, e.get(), wanted[i].second});
  }
  return guard;
}

void TileLockTable::Unref(const std::vector<Guard::Held>& held) {
  std::lock_guard lock(mu_);
  for (const Guard::Held& h : held) {
    if (--h.entry->users == 0) entries_.erase(h.key);
  }
}

size_t TileLockTable::entry_count() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

}  // namespace bgkmap
