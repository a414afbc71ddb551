#include "bgkmap/server/latency_histogram.h"

#include <algorithm>

namespace bgkmap {

void LatencyHistogram::Record(std::chrono::steady_clock::duration elapsed) {
  const int64_t ns =
      std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::nanoseconds>(elapsed).count());
  const double seconds = static_cast<double>(ns) * 1e-9;
  const size_t bucket = static_cast<size_t>(
      std::lower_bound(kLatencyBucketBounds.begin(), kLatencyBucketBounds.end(), seconds) -
      kLatencyBucketBounds.begin());
  buckets_[bucket].fetch_add(1, std::memory_order_relaxed);
  sum_ns_.fetch_add(static_cast<uint64_t>(ns), std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
}

LatencySnapshot LatencyHistogram::Snapshot() const {
  LatencySnapshot s;
  uint64_t running = 0;
  for (size_t i = 0; i < buckets_.size(); ++i) {
    running += buckets_[i].load(std::memory_order_relaxed);
    s.cumulative[i] = running;
  }
  // The +Inf bucket and the count are one figure in the format: keep them equal.
  s.count = running;
  s.sum_seconds = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) * 1e-9;
  return s;
}

std::string_view RequestPhaseName(RequestPhase phase) {
  switch (phase) {
    case RequestPhase::kRegionRead:
      return "region_read";
    case RequestPhase::kRegionStream:
      return "region_stream";
    case RequestPhase::kPoints:
      return "points";
    case RequestPhase::kCheckPath:
      return "check_path";
    case RequestPhase::kScan:
      return "scan";
  }
  return "unknown";
}

}  // namespace bgkmap
