// Decides float vs double for the elevation statistics by measurement: 10^6 observations of
// one cell at a realistic absolute altitude must give a mean within 1 mm of the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bgkmap/core/terrain_map.h"

namespace bgkmap {
namespace {

constexpr double kTruth = 1523.4567;  // metres: a robot on a plateau, UTM-style heights
constexpr int kObservations = 1'000'000;

TEST(NumericStabilityTest, MillionObservationsOfOneCellStayWithinOneMillimetre) {
  MapParams p;
  p.min_range = 0;
  p.dynamics = Dynamics::kOff;  // the sums themselves, uncapped
  auto map = std::move(TerrainMap::Create(p)).value();
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, 0.03);
  Pose pose;
  pose.translation = {100.0, 200.0, kTruth + 1.5};
  float float_w = 0, float_s = 0;  // what float accumulators would have produced
  for (int i = 0; i < kObservations; ++i) {
    const double z = kTruth + noise(rng);
    const Point3f pt{0.05f, 0.05f, static_cast<float>(z - pose.translation.z())};
    ASSERT_TRUE(map->IntegrateScan(std::span<const Point3f>(&pt, 1), pose).ok());
    const double y = pose.translation.z() + static_cast<double>(pt.z);
    float_w += 1.0f;
    float_s += static_cast<float>(y);
  }
  const CellEstimate e = map->EstimateAt(100.05, 200.05);
  const double error = std::abs(static_cast<double>(e.elevation) - kTruth);
  const double float_error = std::abs(static_cast<double>(float_s / float_w) - kTruth);
  RecordProperty("double_error_m", std::to_string(error));
  RecordProperty("float_error_m", std::to_string(float_error));
  std::printf("mean error after %d observations: double %.2e m, float %.2e m\n", kObservations,
              error, float_error);
  // float elevation is only ~0.1 mm resolution at 1500 m; the sum itself is what must be exact.
  EXPECT_LT(error, 1e-3);
  EXPECT_GT(float_error, 1e-3) << "float accumulators would have been enough after all";
  EXPECT_FLOAT_EQ(e.elevation_weight, static_cast<float>(kObservations));
}

}  // namespace
}  // namespace bgkmap
