#include "bgkmap/sim/max_mipmap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace bgkmap::sim {
namespace {

TEST(MaxMipmapTest, BoundsEveryRectangleAndIsExactOnOneCell) {
  const int64_t cols = 37, rows = 23;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  std::vector<float> v(cols * rows);
  for (float& x : v) x = u(rng);
  v[5] = -std::numeric_limits<float>::infinity();  // a cell without data
  const MaxMipmap m(cols, rows, v);
  std::uniform_int_distribution<int64_t> uc(0, cols - 1), ur(0, rows - 1);
  for (int trial = 0; trial < 2000; ++trial) {
    const int64_t c0 = uc(rng), c1 = uc(rng), r0 = ur(rng), r1 = ur(rng);
    float truth = -std::numeric_limits<float>::infinity();
    for (int64_t r = std::min(r0, r1); r <= std::max(r0, r1); ++r) {
      for (int64_t c = std::min(c0, c1); c <= std::max(c0, c1); ++c) {
        truth = std::max(truth, v[r * cols + c]);
      }
    }
    ASSERT_GE(m.Max(c0, r0, c1, r1), truth);
    ASSERT_EQ(m.Max(c0, r0, c0, r0), v[r0 * cols + c0]);
  }
}

TEST(MaxMipmapTest, RectanglesOutsideTheGridAreEmpty) {
  const MaxMipmap m(4, 4, std::vector<float>(16, 2.0f));
  EXPECT_TRUE(std::isinf(m.Max(10, 0, 12, 3)));
  EXPECT_TRUE(std::isinf(m.Max(-5, -5, -1, -1)));
  EXPECT_EQ(m.Max(-5, -5, 0, 0), 2.0f);  // clamped
  EXPECT_TRUE(std::isinf(MaxMipmap().Max(0, 0, 1, 1)));
}

}  // namespace
}  // namespace bgkmap::sim
