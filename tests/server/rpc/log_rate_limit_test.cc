// Refusals are logged at most N times a second, and what was left out is counted
// (rpc/log_rate_limit.h; issue 25: 650 KB/s of log from unauthenticated calls).
#include "rpc/log_rate_limit.h"

#include <gtest/gtest.h>

namespace bgkmap {
namespace {

TEST(LogRateLimitTest, AtMostNLinesASecondAndTheRestCounted) {
  LogRateLimit limit(3);
  const LogRateLimit::Clock::time_point t0{std::chrono::seconds(100)};
  uint64_t suppressed = 99;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(limit.Allow(t0 + std::chrono::milliseconds(i), &suppressed));
    EXPECT_EQ(suppressed, 0u);
  }
  for (int i = 0; i < 1000; ++i) {
    EXPECT_FALSE(limit.Allow(t0 + std::chrono::milliseconds(500), &suppressed));
  }
  // The next second lets lines through again; the first names what was left out.
  ASSERT_TRUE(limit.Allow(t0 + std::chrono::milliseconds(1000), &suppressed));
  EXPECT_EQ(suppressed, 1000u);
  ASSERT_TRUE(limit.Allow(t0 + std::chrono::milliseconds(1001), &suppressed));
  EXPECT_EQ(suppressed, 0u);
}

}  // namespace
}  // namespace bgkmap
