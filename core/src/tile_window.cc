#include <algorithm>

#include "bgkmap/core/scan_integrator.h"

namespace bgkmap {

TileWindow::TileWindow(const std::vector<TileKey>& keys) {
  if (keys.empty()) return;
  min_ = max_ = keys.front();
  for (const TileKey& k : keys) {
    min_ = {std::min(min_.x, k.x), std::min(min_.y, k.y)};
    max_ = {std::max(max_.x, k.x), std::max(max_.y, k.y)};
  }
  width_ = static_cast<size_t>(int64_t{max_.x} - min_.x + 1);
  const size_t area = width_ * static_cast<size_t>(int64_t{max_.y} - min_.y + 1);
  if (area <= 4 * keys.size() + 4096) {
    dense_.assign(area, nullptr);
  } else {
    for (const TileKey& k : keys) sparse_.emplace_back(k, nullptr);
  }
}

void TileWindow::set(TileKey k, Tile* t) {
  if (!dense_.empty()) {
    dense_[static_cast<size_t>(k.y - min_.y) * width_ + (k.x - min_.x)] = t;
    return;
  }
  auto it = std::lower_bound(sparse_.begin(), sparse_.end(), k,
                             [](const auto& e, const TileKey& key) { return e.first < key; });
  if (it != sparse_.end() && it->first == k) it->second = t;
}

Tile* TileWindow::SparseAt(TileKey k) const {
  auto it = std::lower_bound(sparse_.begin(), sparse_.end(), k,
                             [](const auto& e, const TileKey& key) { return e.first < key; });
  return it != sparse_.end() && it->first == k ? it->second : nullptr;
}

}  // namespace bgkmap
