#include "bgkmap/server/heap_policy.h"

#include <malloc.h>

#include <atomic>
#include <cstdlib>
#include <mutex>

#include "bgkmap/core/thread_scratch.h"

namespace bgkmap {
namespace {

constexpr int kKeptMmapThreshold = 256 << 20;
constexpr int kKeptTrimThreshold = 1 << 30;
// While returning: an arena's top beyond this goes back at the next free that reaches it.
constexpr int kReturningTrimThreshold = 128 << 10;

std::atomic<bool> keeping{false};
std::mutex returning_mu;
int returning = 0;  // windows open (guarded by returning_mu)

}  // namespace

void KeepLargeAllocationsInHeap() {
  mallopt(M_MMAP_THRESHOLD, kKeptMmapThreshold);
  mallopt(M_TRIM_THRESHOLD, kKeptTrimThreshold);
  keeping.store(true);
}

void LimitHeapArenas(int arenas) {
  if (arenas <= 0 || std::getenv("MALLOC_ARENA_MAX") != nullptr) return;
  mallopt(M_ARENA_MAX, arenas);
}

void BeginReturningFreedMemory() {
  std::lock_guard lock(returning_mu);
  if (returning++ == 0 && keeping.load()) mallopt(M_TRIM_THRESHOLD, kReturningTrimThreshold);
}

void EndReturningFreedMemory() {
  malloc_trim(0);
  std::lock_guard lock(returning_mu);
  if (--returning == 0 && keeping.load()) mallopt(M_TRIM_THRESHOLD, kKeptTrimThreshold);
}

void ReturnThreadScratch() {
  BeginReturningFreedMemory();
  ReleaseThreadScratch();
  EndReturningFreedMemory();
}

}  // namespace bgkmap
