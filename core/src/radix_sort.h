// LSD radix sort of 64-bit keys, returning the stable sorting permutation. A scan's keys are
// dense cell offsets within the scan's bounding box (CellSortKey), so their high digits are zero
// for all and are skipped.
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap::internal {

std::vector<uint32_t> RadixSortOrder(const std::vector<uint64_t>& keys);

// The key of the cell (dx, dy) cells from a box's low corner in a box `height` cells tall: keys
// ascend in (x, y) order, and a box of w x h cells needs only log2(w h) bits of them.
inline uint64_t CellSortKey(int64_t dx, int64_t dy, uint64_t height) {
  return static_cast<uint64_t>(dx) * height + static_cast<uint64_t>(dy);
}

}  // namespace bgkmap::internal
