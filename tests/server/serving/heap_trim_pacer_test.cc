// HeapTrimPacer: packed tiles are trimmed at most once per gap, a trim put off is done once the
// gap has passed, evictions are trimmed at once.
#include "serving/heap_trim_pacer.h"

#include <gtest/gtest.h>

namespace bgkmap {
namespace {

using std::chrono::milliseconds;

TEST(HeapTrimPacerTest, PackingIsTrimmedAtMostOncePerGap) {
  HeapTrimPacer pacer(milliseconds(2000));
  const HeapTrimPacer::Clock::time_point t0{};
  EXPECT_FALSE(pacer.TrimNow(t0, false, false)) << "nothing freed";
  EXPECT_TRUE(pacer.TrimNow(t0 + milliseconds(10), true, false)) << "the first trim is not put off";
  // A streaming server packs after every scan: none of these trims within the gap.
  for (int ms = 100; ms < 2010; ms += 100) {
    EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(ms), true, false)) << ms;
  }
  EXPECT_TRUE(pacer.TrimNow(t0 + milliseconds(2010), true, false));
  EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(2020), false, false));
}

TEST(HeapTrimPacerTest, ATrimPutOffIsDoneOnceTheGapHasPassed) {
  HeapTrimPacer pacer(milliseconds(2000));
  const HeapTrimPacer::Clock::time_point t0{};
  ASSERT_TRUE(pacer.TrimNow(t0, true, false));
  EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(500), true, false));  // the last packing
  // The server went quiet: later passes free nothing, the packed arrays still go back.
  EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(1500), false, false));
  EXPECT_TRUE(pacer.TrimNow(t0 + milliseconds(2500), false, false));
  EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(5000), false, false)) << "only once";
}

TEST(HeapTrimPacerTest, EvictionsAreTrimmedAtOnce) {
  HeapTrimPacer pacer(milliseconds(2000));
  const HeapTrimPacer::Clock::time_point t0{};
  ASSERT_TRUE(pacer.TrimNow(t0, true, false));
  EXPECT_TRUE(pacer.TrimNow(t0 + milliseconds(1), true, true));
  EXPECT_TRUE(pacer.TrimNow(t0 + milliseconds(2), false, true));
  // Packing right after an eviction's trim waits for the gap again.
  EXPECT_FALSE(pacer.TrimNow(t0 + milliseconds(3), true, false));
}

}  // namespace
}  // namespace bgkmap
