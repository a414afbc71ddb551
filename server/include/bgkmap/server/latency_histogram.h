// Latency histograms for /metrics: how long the phases of requests take (a region query's read
// and its transfer, a point query, a path check, a scan from receipt to ack), so an operator
// can tell a slow map from a slow network or a queue. Fixed buckets (Prometheus' cumulative
// `le` bounds), lock-free: recording is a few relaxed atomic additions on the request's thread.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <string_view>

namespace bgkmap {

// Upper bounds of the buckets in seconds, ascending; a last bucket (+Inf) takes the rest.
inline constexpr std::array<double, 14> kLatencyBucketBounds = {
    0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10};

// What a scrape reads of one histogram. Read field by field while requests record, so the
// counts may be a few requests apart; each count is exact once recording stops.
struct LatencySnapshot {
  // cumulative[i]: durations <= kLatencyBucketBounds[i]; the last entry counts all (+Inf).
  std::array<uint64_t, kLatencyBucketBounds.size() + 1> cumulative{};
  uint64_t count = 0;
  double sum_seconds = 0;
};

class LatencyHistogram {
 public:
  // Thread-safe. A negative duration counts as 0.
  void Record(std::chrono::steady_clock::duration elapsed);
  LatencySnapshot Snapshot() const;

 private:
  std::array<std::atomic<uint64_t>, kLatencyBucketBounds.size() + 1> buckets_{};
  std::atomic<uint64_t> count_{0};
  std::atomic<uint64_t> sum_ns_{0};
};

// The phases the server times, one histogram each (the `phase` label of
// bgkmap_request_phase_seconds).
enum class RequestPhase {
  kRegionRead,    // QueryRegion: request to raster read (query pool queue, tile locks, extraction)
  kRegionStream,  // QueryRegion: raster read to the last chunk taken by the client
  kPoints,        // QueryPoints: request to answer (queue and read; not the transfer)
  kCheckPath,     // CheckPath: request to answer
  kScan,          // a scan, streamed or unary: received to acknowledged (prepared, integrated,
                  // logged)
};
inline constexpr RequestPhase kRequestPhases[] = {
    RequestPhase::kRegionRead, RequestPhase::kRegionStream, RequestPhase::kPoints,
    RequestPhase::kCheckPath, RequestPhase::kScan};
std::string_view RequestPhaseName(RequestPhase phase);

// One histogram per phase; shared by the handlers, read by scrapes.
class RequestLatencies {
 public:
  LatencyHistogram& of(RequestPhase phase) { return histograms_[static_cast<size_t>(phase)]; }
  const LatencyHistogram& of(RequestPhase phase) const {
    return histograms_[static_cast<size_t>(phase)];
  }

 private:
  std::array<LatencyHistogram, std::size(kRequestPhases)> histograms_;
};

}  // namespace bgkmap
