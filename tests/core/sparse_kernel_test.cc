#include "bgkmap/core/sparse_kernel.h"

#include <gtest/gtest.h>

#include <cmath>

namespace bgkmap {
namespace {

TEST(SparseKernelTest, IsOneAtZeroAndZeroAtAndBeyondSupport) {
  EXPECT_DOUBLE_EQ(SparseKernel(0.0, 0.3), 1.0);
  EXPECT_EQ(SparseKernel(0.3, 0.3), 0.0);
  EXPECT_EQ(SparseKernel(0.5, 0.3), 0.0);
  EXPECT_NEAR(SparseKernel(0.5, 1.0), 1.0 / 6.0, 1e-12);  // (2 + cos pi)/3 * 0.5 + sin(pi)/2pi
}

TEST(SparseKernelTest, DecreasesMonotonicallyAndStaysNonNegative) {
  double prev = 1.0;
  for (int i = 1; i < 1000; ++i) {
    const double k = SparseKernel(i * 1e-3, 1.0);
    EXPECT_LE(k, prev) << "d = " << i * 1e-3;
    EXPECT_GE(k, 0.0);
    prev = k;
  }
}

TEST(SparseKernelTest, IsSymmetricInDistanceSign) {
  EXPECT_DOUBLE_EQ(SparseKernel(-0.1, 0.3), SparseKernel(0.1, 0.3));
}

TEST(KernelStencilTest, HoldsExactlyTheOffsetsCloserThanL) {
  for (const auto& [res, l] : {std::pair{0.1, 0.3}, {0.1, 1.0}, {0.25, 0.3}, {0.1, 0.1}}) {
    const KernelStencil s(res, l);
    int expected = 0;
    for (int dy = -20; dy <= 20; ++dy) {
      for (int dx = -20; dx <= 20; ++dx) expected += res * std::hypot(dx, dy) < l ? 1 : 0;
    }
    EXPECT_EQ(s.cell_count(), expected) << "res " << res << " l " << l;
    // Row dy = 0 is the centre row; its centre weight is k(0) = 1.
    const int mid = s.radius();
    EXPECT_EQ(s.row_weights_double(mid)[s.half_width(mid)], 1.0);
    for (int r = 0; r < s.row_count(); ++r) {
      const int dy = r - s.radius();
      EXPECT_EQ(s.half_width(r), s.half_width(s.row_count() - 1 - r)) << "symmetric in dy";
      for (int j = 0; j <= 2 * s.half_width(r); ++j) {
        const int dx = j - s.half_width(r);
        EXPECT_DOUBLE_EQ(s.row_weights_double(r)[j], SparseKernel(res * std::hypot(dx, dy), l));
      }
    }
  }
}

TEST(KernelStencilTest, PaperSettingsHaveExpectedSize) {
  EXPECT_EQ(KernelStencil(0.1, 0.3).cell_count(), 25);  // dx^2 + dy^2 < 9
  EXPECT_EQ(KernelStencil(0.1, 0.3).radius(), 2);
  EXPECT_EQ(KernelStencil(0.1, 1.0).radius(), 9);
}

}  // namespace
}  // namespace bgkmap
