#include "scratch_buffer.h"

#include "bgkmap/core/thread_scratch.h"

namespace bgkmap {
namespace internal {
namespace {

// Filled during static initialization only, read-only afterwards: no lock needed.
std::vector<KeptScratch>& Kinds() {
  static std::vector<KeptScratch> kinds;
  return kinds;
}

}  // namespace

bool RegisterKeptScratch(KeptScratch kind) {
  Kinds().push_back(kind);
  return true;
}

}  // namespace internal

void ReleaseThreadScratch() {
  for (const internal::KeptScratch& kind : internal::Kinds()) kind.release();
}

std::size_t ThreadScratchBytes() {
  std::size_t bytes = 0;
  for (const internal::KeptScratch& kind : internal::Kinds()) bytes += kind.bytes();
  return bytes;
}

}  // namespace bgkmap
