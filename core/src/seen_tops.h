// The free-space test's per-cell reads, remembered for one scan: a dense scan's rays cross each
// cell near its returns ten times or more, and the top of what a cell has seen is the same every
// time (the map as the scan finds it). Internal to core.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/scan.h"

namespace bgkmap::internal {

class SeenTops {
 public:
  // Not yet read.
  static constexpr double kUnread = std::numeric_limits<double>::quiet_NaN();
  // An unknown cell: no ray height is below it, so it is never contradicted.
  static constexpr double kNone = -std::numeric_limits<double>::infinity();

  // For the tiles `scan` may read or change (its sorted, disjoint tile lists), `cells` per tile.
  SeenTops(const PreparedScan& scan, int cells) : cells_(cells) {
    keys_.reserve(scan.write_tiles.size() + scan.read_tiles.size() + scan.clear_tiles.size());
    for (const auto* list : {&scan.write_tiles, &scan.read_tiles, &scan.clear_tiles}) {
      keys_.insert(keys_.end(), list->begin(), list->end());
    }
    std::sort(keys_.begin(), keys_.end());
    slab_of_.assign(keys_.size(), -1);
    Scratch().clear();
  }

  // The remembered tops of tile `key`'s cells (kUnread until read). Valid until the next call.
  double* Of(TileKey key) {
    auto it = std::lower_bound(keys_.begin(), keys_.end(), key);
    if (it == keys_.end() || *it != key) {  // not in the scan's lists (a wider window): added
      slab_of_.insert(slab_of_.begin() + (it - keys_.begin()), -1);
      it = keys_.insert(it, key);
    }
    int32_t& slab = slab_of_[it - keys_.begin()];
    std::vector<double>& tops = Scratch();
    if (slab < 0) {  // first visit: a slab of unread cells
      slab = static_cast<int32_t>(tops.size() / cells_);
      tops.resize(tops.size() + cells_, kUnread);
    }
    return tops.data() + static_cast<size_t>(slab) * cells_;
  }

 private:
  // One buffer per thread, kept from scan to scan: no allocation once it has grown.
  static std::vector<double>& Scratch() {
    thread_local std::vector<double> tops;
    return tops;
  }

  int cells_;
  std::vector<TileKey> keys_;
  std::vector<int32_t> slab_of_;
};

}  // namespace bgkmap::internal
