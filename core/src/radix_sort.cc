#include "radix_sort.h"

#include <array>
#include <cstddef>

#include "scratch_buffer.h"

namespace bgkmap::internal {
namespace {

// The passes' buffers are kept per thread from scan to scan (scratch_buffer.h): a scan's
// megabytes of fresh pages each time cost more page faults than the sort itself.
thread_local std::vector<uint32_t> order_tmp;
thread_local std::vector<uint64_t> sorted, sorted_tmp;

const bool kKept = RegisterKeptScratch(
    {[] {
       std::vector<uint32_t>().swap(order_tmp);
       std::vector<uint64_t>().swap(sorted);
       std::vector<uint64_t>().swap(sorted_tmp);
     },
     [] { return CapacityBytes(order_tmp) + CapacityBytes(sorted) + CapacityBytes(sorted_tmp); }});

}  // namespace

std::vector<uint32_t> RadixSortOrder(const std::vector<uint64_t>& keys) {
  const std::size_t n = keys.size();
  std::vector<uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  order_tmp.resize(n);
  sorted_tmp.resize(n);
  // The keys move with their indices (sequential reads per pass instead of a gather).
  sorted.assign(keys.begin(), keys.end());
  uint64_t all_bits = 0;
  for (uint64_t k : keys) all_bits |= k;
  // The counts of every byte some key has bits in, in one read of the keys.
  std::array<int, 8> bytes{};
  int nbytes = 0;
  for (int b = 0; b < 8; ++b) {
    if ((all_bits >> (8 * b)) & 0xff) bytes[nbytes++] = b;
  }
  std::array<std::array<uint32_t, 257>, 8> count{};
  for (uint64_t k : keys) {
    for (int j = 0; j < nbytes; ++j) ++count[j][((k >> (8 * bytes[j])) & 0xff) + 1];
  }
  for (int j = 0; j < nbytes; ++j) {
    const int b = bytes[j];
    std::array<uint32_t, 257>& c = count[j];
    // A byte every key shares orders nothing: the stable pass would be the identity.
    bool shared = false;
    for (int v = 1; v <= 256 && !shared; ++v) shared = c[v] == n;
    if (shared) continue;
    for (int v = 0; v < 256; ++v) c[v + 1] += c[v];
    const int shift = 8 * b;
    for (std::size_t i = 0; i < n; ++i) {
      const uint32_t at = c[(sorted[i] >> shift) & 0xff]++;
      sorted_tmp[at] = sorted[i];
      order_tmp[at] = order[i];
    }
    sorted.swap(sorted_tmp);
    order.swap(order_tmp);
  }
  ReleaseIfLarge(order_tmp);
  ReleaseIfLarge(sorted);
  ReleaseIfLarge(sorted_tmp);
  return order;
}

}  // namespace bgkmap::internal
