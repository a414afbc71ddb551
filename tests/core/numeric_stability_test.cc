// Decides float vs double for the elevation statistics by measurement: 10^6 observations of
// one cell at a realistic absolute altitude must give a mean within 1 mm of the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

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

// bgk-ll's plane moments at altitude: Suy and Svy are ~1523 times Su and Sv, and the slope is
// their difference (FitLocalPlane centres y on the mean first). 20,000 noisy scans of a sloped
// 5 x 5 patch at 1523 m must still extrapolate the plane to the unobserved cell beyond its edge
// within 1 mm. Mutation: the slopes solved from the uncentred moments (Suy, Svy instead
// of Suy - mean Su, Svy - mean Sv) -> metres off.
TEST(NumericStabilityTest, BgkLlPlaneAtAltitudeExtrapolatesWithinOneMillimetre) {
  MapParams p;
  p.min_range = 0;
  p.dynamics = Dynamics::kOff;
  p.method = Method::kBgkLocalLinear;
  p.kernel_length = 0.5;  // the cell beyond the edge reaches four columns: a slope across
  auto map = std::move(TerrainMap::Create(p)).value();
  const auto plane = [](double x, double y) { return kTruth + 0.2 * x - 0.1 * y; };
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.03);
  Pose pose;
  pose.translation = {0.0, 0.0, kTruth + 1.5};
  std::vector<Point3f> points;
  for (int scan = 0; scan < 20'000; ++scan) {
    points.clear();
    for (int ix = 0; ix < 5; ++ix) {
      for (int iy = 0; iy < 5; ++iy) {
        const double x = (ix + 0.5) * p.resolution, y = (iy + 0.5) * p.resolution;
        const double z = plane(x, y) + noise(rng);
        points.push_back({static_cast<float>(x), static_cast<float>(y),
                          static_cast<float>(z - pose.translation.z())});
      }
    }
    ASSERT_TRUE(map->IntegrateScan(points, pose).ok());
  }
  const double x = 5.5 * p.resolution, y = 2.5 * p.resolution;  // unobserved, beyond the edge
  const CellEstimate e = map->EstimateAt(x, y);
  const double error = std::abs(static_cast<double>(e.elevation) - plane(x, y));
  std::printf("bgk-ll extrapolation error at %.0f m after 500,000 observations: %.2e m\n", kTruth,
              error);
  EXPECT_LT(error, 1e-3);
}

}  // namespace
}  // namespace bgkmap
