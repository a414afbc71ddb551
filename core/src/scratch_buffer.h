// Per-thread scratch vectors of the per-scan work, kept from scan to scan so a dense scan's
// megabytes are not allocated, zeroed and faulted in every time, but not without bound: one
// huge scan (server.max_points_per_scan allows 2 M points) must not pin its buffers in every
// thread of a long-running server, and an idle thread can hand them all back
// (bgkmap/core/thread_scratch.h). Internal to core.
#pragma once

#include <cstddef>
#include <vector>

namespace bgkmap::internal {

// What a kept buffer may hold: a 128-beam scan's half million points at 16 bytes.
inline constexpr std::size_t kScratchKeepBytes = std::size_t{8} << 20;

// Frees `v` if it holds more than kScratchKeepBytes; call it when the scan is done with `v`.
template <typename T>
void ReleaseIfLarge(std::vector<T>& v) {
  if (v.capacity() * sizeof(T) > kScratchKeepBytes) std::vector<T>().swap(v);
}

// One kind of kept buffer: `release` frees the calling thread's, `bytes` tells what it holds.
struct KeptScratch {
  void (*release)();
  std::size_t (*bytes)();
};

// Adds a kind of kept buffer to what ReleaseThreadScratch frees. Call it only during static
// initialization (a namespace-scope constant of the buffer's file), before any thread uses it.
bool RegisterKeptScratch(KeptScratch kind);

template <typename T>
std::size_t CapacityBytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

}  // namespace bgkmap::internal
