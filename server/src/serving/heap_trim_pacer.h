// When the maintenance thread hands freed memory back to the system (malloc_trim). A trim walks
// every arena and drops each free page, which the next scans and answers fault in again: on a
// VM a fault costs microseconds, and trimming after every packing pass of a streaming server
// cost ~1,000 more faults a scan and ~40 % of its CPU (docs/benchmarks.md, "Trimming the
// heap"). Tiles only packed are trimmed at most once per `gap` (the freed arrays are what the
// next new tiles reuse); a pass that evicted tiles under storage.max_memory_mb is trimmed at once
// (the bound is about the process's memory). A trim put off is done once the gap has passed,
// freed or not.
#pragma once

#include <chrono>

namespace bgkmap {

class HeapTrimPacer {
 public:
  using Clock = std::chrono::steady_clock;

  explicit HeapTrimPacer(Clock::duration gap) : gap_(gap) {}

  // A maintenance pass ended at `now`; `packed`, `evicted`: whether it freed tiles so. True when
  // the caller should trim now (the pacer then counts it as done).
  bool TrimNow(Clock::time_point now, bool packed, bool evicted) {
    pending_ = pending_ || packed || evicted;
    if (!pending_ || (!evicted && trimmed_once_ && now - last_trim_ < gap_)) return false;
    pending_ = false;
    trimmed_once_ = true;
    last_trim_ = now;
    return true;
  }

 private:
  const Clock::duration gap_;
  bool pending_ = false;
  bool trimmed_once_ = false;
  Clock::time_point last_trim_{};
};

}  // namespace bgkmap
