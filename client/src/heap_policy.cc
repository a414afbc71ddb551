#include "bgkmap/client/heap_policy.h"

#include <malloc.h>

#include <cstdlib>

namespace bgkmap {

void KeepFreedHeapMemoryForReuse() {
  if (std::getenv("GLIBC_TUNABLES") != nullptr) return;
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
}

}  // namespace bgkmap
