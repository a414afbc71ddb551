#include "bgkmap/eval/roc.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace bgkmap::eval {
namespace {

TEST(RocTest, PerfectSeparationHasAucOne) {
  const std::vector<double> s = {0.9, 0.8, 0.2, 0.1};
  const std::vector<uint8_t> pos = {1, 1, 0, 0};
  const Roc roc = ComputeRoc(s, pos);
  EXPECT_DOUBLE_EQ(roc.auc, 1.0);
  EXPECT_EQ(roc.positives, 2);
  EXPECT_EQ(roc.negatives, 2);
  EXPECT_DOUBLE_EQ(roc.curve.back().fpr, 1.0);
  EXPECT_DOUBLE_EQ(roc.curve.back().tpr, 1.0);
}

TEST(RocTest, InvertedScoresHaveAucZero) {
  const Roc roc = ComputeRoc(std::vector<double>{0.1, 0.9}, std::vector<uint8_t>{1, 0});
  EXPECT_DOUBLE_EQ(roc.auc, 0.0);
}

TEST(RocTest, TiesCountHalf) {
  // All scores equal: one diagonal step, AUC 1/2 (the Mann-Whitney convention).
  const Roc roc = ComputeRoc(std::vector<double>{0.5, 0.5, 0.5}, std::vector<uint8_t>{1, 0, 0});
  EXPECT_DOUBLE_EQ(roc.auc, 0.5);
}

TEST(RocTest, MatchesPairCountingOnAMixedExample) {
  const std::vector<double> s = {0.9, 0.7, 0.7, 0.4, 0.3, 0.1};
  const std::vector<uint8_t> pos = {1, 0, 1, 1, 0, 0};
  double pairs = 0;
  for (size_t i = 0; i < s.size(); ++i)
    for (size_t j = 0; j < s.size(); ++j)
      if (pos[i] && !pos[j]) pairs += s[i] > s[j] ? 1.0 : (s[i] == s[j] ? 0.5 : 0.0);
  EXPECT_NEAR(ComputeRoc(s, pos).auc, pairs / 9.0, 1e-12);
}

TEST(RocTest, OneClassOnlyHasNoAuc) {
  EXPECT_TRUE(
      std::isnan(ComputeRoc(std::vector<double>{0.1, 0.2}, std::vector<uint8_t>{0, 0}).auc));
}

TEST(RocTest, ThinKeepsBothEnds) {
  std::vector<RocPoint> c;
  for (int i = 0; i <= 1000; ++i) c.push_back({i / 1000.0, i / 1000.0});
  const auto t = Thin(c, 10);
  ASSERT_EQ(t.size(), 10u);
  EXPECT_DOUBLE_EQ(t.front().fpr, 0.0);
  EXPECT_DOUBLE_EQ(t.back().fpr, 1.0);
}

}  // namespace
}  // namespace bgkmap::eval
