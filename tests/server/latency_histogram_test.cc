// LatencyHistogram: a duration lands in the first bucket whose bound it does not exceed (the
// `le` of the exposition), cumulative counts end at the count, the sum is the durations' sum,
// and concurrent recording loses nothing.
#include "bgkmap/server/latency_histogram.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

namespace bgkmap {
namespace {

using std::chrono::nanoseconds;

TEST(LatencyHistogramTest, ADurationOnABoundCountsInThatBucket) {
  LatencyHistogram h;
  h.Record(nanoseconds(500'000));         // exactly 0.0005 s: le="0.0005"
  h.Record(nanoseconds(500'001));         // just above: le="0.001"
  h.Record(nanoseconds(-5));              // a clock step back: counted as 0
  h.Record(nanoseconds(11'000'000'000));  // beyond the last bound: +Inf only
  const LatencySnapshot s = h.Snapshot();
  EXPECT_EQ(s.cumulative[0], 2u);  // 0 and 0.0005 s
  EXPECT_EQ(s.cumulative[1], 3u);
  EXPECT_EQ(s.cumulative[kLatencyBucketBounds.size() - 1], 3u);  // le="10"
  EXPECT_EQ(s.cumulative.back(), 4u);                            // +Inf
  EXPECT_EQ(s.count, 4u);
  EXPECT_NEAR(s.sum_seconds, 0.0005 + 0.000500001 + 11.0, 1e-9);
}

TEST(LatencyHistogramTest, ConcurrentRecordsAreAllCounted) {
  LatencyHistogram h;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&h, t] {
      for (int i = 0; i < 10'000; ++i) h.Record(nanoseconds(1'000'000 * (t + 1)));
    });
  }
  for (std::thread& t : threads) t.join();
  const LatencySnapshot s = h.Snapshot();
  EXPECT_EQ(s.count, 40'000u);
  EXPECT_EQ(s.cumulative[1], 10'000u);  // 1 ms: le="0.001"
  EXPECT_EQ(s.cumulative[2], 20'000u);  // 2 ms: le="0.002"
  EXPECT_EQ(s.cumulative[3], 40'000u);  // 3 and 4 ms: le="0.005"
  EXPECT_NEAR(s.sum_seconds, 10'000 * (0.001 + 0.002 + 0.003 + 0.004), 1e-6);
}

TEST(LatencyHistogramTest, EveryPhaseHasItsOwnHistogramAndName) {
  RequestLatencies latencies;
  latencies.of(RequestPhase::kScan).Record(nanoseconds(1));
  for (RequestPhase phase : kRequestPhases) {
    EXPECT_EQ(latencies.of(phase).Snapshot().count, phase == RequestPhase::kScan ? 1u : 0u);
    EXPECT_NE(RequestPhaseName(phase), "unknown");
  }
  EXPECT_EQ(RequestPhaseName(RequestPhase::kRegionStream), "region_stream");
}

}  // namespace
}  // namespace bgkmap
