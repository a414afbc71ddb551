// Pose corrections in progress and done since start, for Info and /metrics.
#pragma once

#include <cstdint>

namespace bgkmap {

struct CorrectionStats {
  uint64_t in_progress = 0;
  uint64_t applied = 0;
  uint64_t failed = 0;  // refused (nothing changed)
  uint64_t scans_revised = 0;
  uint64_t records_replayed = 0;
  double last_seconds = 0;  // the last one applied, request to switch
};

}  // namespace bgkmap
