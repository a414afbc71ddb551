// LSD radix sort of 64-bit keys, returning the stable sorting permutation. A scan's keys are
// cell offsets within the scan's bounding box, so most high bytes are the same for all and are
// skipped.
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap::internal {

std::vector<uint32_t> RadixSortOrder(const std::vector<uint64_t>& keys);

}  // namespace bgkmap::internal
