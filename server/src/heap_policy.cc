#include "bgkmap/server/heap_policy.h"

#include <malloc.h>

#include <atomic>

namespace bgkmap {
namespace {

constexpr int kKeptMmapThreshold = 256 << 20;
constexpr int kKeptTrimThreshold = 1 << 30;
// While returning: an arena's top beyond this goes back at the next free that reaches it.
constexpr int kReturningTrimThreshold = 128 << 10;

std::atomic<bool> keeping{false};

}  // namespace

void KeepLargeAllocationsInHeap() {
  mallopt(M_MMAP_THRESHOLD, kKeptMmapThreshold);
  mallopt(M_TRIM_THRESHOLD, kKeptTrimThreshold);
  keeping.store(true);
}

void BeginReturningFreedMemory() {
  if (keeping.load()) mallopt(M_TRIM_THRESHOLD, kReturningTrimThreshold);
}

void EndReturningFreedMemory() {
  malloc_trim(0);
  if (keeping.load()) mallopt(M_TRIM_THRESHOLD, kKeptTrimThreshold);
}

}  // namespace bgkmap
