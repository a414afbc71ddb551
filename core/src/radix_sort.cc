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
  // 11-bit digits: a scan's dense cell keys (22-24 bits) sort in two or three passes, and a
  // digit's 2,048 counters stay in L1.
  constexpr int kBits = 11;
  constexpr int kDigits = (64 + kBits - 1) / kBits;
  constexpr uint64_t kMask = (uint64_t{1} << kBits) - 1;
  constexpr size_t kBuckets = size_t{1} << kBits;
  const std::size_t n = keys.size();
  std::vector<uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  order_tmp.resize(n);
  sorted_tmp.resize(n);
  // The keys move with their indices (sequential reads per pass instead of a gather).
  sorted.assign(keys.begin(), keys.end());
  uint64_t all_bits = 0;
  for (uint64_t k : keys) all_bits |= k;
  // The counts of every digit some key has bits in, in one read of the keys.
  std::array<int, kDigits> digits{};
  int ndigits = 0;
  for (int d = 0; d < kDigits; ++d) {
    if ((all_bits >> (kBits * d)) & kMask) digits[ndigits++] = d;
  }
  std::vector<uint32_t> counts(static_cast<size_t>(ndigits) * (kBuckets + 1), 0);
  for (uint64_t k : keys) {
    for (int j = 0; j < ndigits; ++j) {
      ++counts[j * (kBuckets + 1) + ((k >> (kBits * digits[j])) & kMask) + 1];
    }
  }
  for (int j = 0; j < ndigits; ++j) {
    uint32_t* c = counts.data() + j * (kBuckets + 1);
    // A digit every key shares orders nothing: the stable pass would be the identity.
    bool shared = false;
    for (size_t v = 1; v <= kBuckets && !shared; ++v) shared = c[v] == n;
    if (shared) continue;
    for (size_t v = 0; v < kBuckets; ++v) c[v + 1] += c[v];
    const int shift = kBits * digits[j];
    for (std::size_t i = 0; i < n; ++i) {
      const uint32_t at = c[(sorted[i] >> shift) & kMask]++;
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
