#include "radix_sort.h"

#include <array>
#include <cstddef>

namespace bgkmap::internal {

std::vector<uint32_t> RadixSortOrder(const std::vector<uint64_t>& keys) {
  const std::size_t n = keys.size();
  std::vector<uint32_t> order(n), tmp(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  uint64_t all_bits = 0;
  for (uint64_t k : keys) all_bits |= k;
  for (int shift = 0; shift < 64; shift += 8) {
    if (((all_bits >> shift) & 0xff) == 0) continue;  // every key has 0 in this byte
    std::array<uint32_t, 257> count{};
    for (uint64_t k : keys) ++count[((k >> shift) & 0xff) + 1];
    for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
    for (uint32_t idx : order) tmp[count[(keys[idx] >> shift) & 0xff]++] = idx;
    order.swap(tmp);
  }
  return order;
}

}  // namespace bgkmap::internal
