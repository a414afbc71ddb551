#include "bgkmap/core/terrain_features.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "bgkmap/core/scan_integrator.h"

namespace bgkmap {
namespace {

std::vector<PatchPoint> Patch(double res, double radius, double (*z)(double, double)) {
  std::vector<PatchPoint> pts;
  for (const CellIndex& o : DiskOffsets(radius, res)) {
    const double x = o.x * res, y = o.y * res;
    pts.push_back({x, y, z(x, y)});
  }
  return pts;
}

TEST(TerrainFeaturesTest, FlatGroundIsPerfectlyTraversable) {
  const auto patch = Patch(0.1, 0.3, [](double, double) { return 5.0; });
  const TerrainFeatures f = ComputeFeatures(patch);
  EXPECT_NEAR(f.step, 0.0, 1e-12);
  EXPECT_NEAR(f.slope_deg, 0.0, 1e-6);
  EXPECT_NEAR(f.roughness, 0.0, 1e-6);
  EXPECT_NEAR(TraversabilityValue(f, MapParams{}), 0.0, 1e-5);
}

TEST(TerrainFeaturesTest, TiltedPlaneGivesItsSlopeAndNoRoughness) {
  for (double deg : {5.0, 10.0, 15.0, 30.0}) {
    static double t;
    t = std::tan(deg * std::numbers::pi / 180.0);
    // A plane descending along a skew direction, at a UTM-sized altitude.
    const auto patch =
        Patch(0.1, 0.3, [](double x, double y) { return 1234.5 + t * (0.6 * x + 0.8 * y); });
    const TerrainFeatures f = ComputeFeatures(patch);
    EXPECT_NEAR(f.slope_deg, deg, 1e-4) << deg;
    EXPECT_NEAR(f.roughness, 0.0, 1e-5) << deg;
    // Step: 0.6x + 0.8y peaks at offset (2, 2) cells over the radius-0.3 patch: +-0.28 m.
    EXPECT_NEAR(f.step, t * 0.56, 1e-9) << deg;
  }
}

TEST(TerrainFeaturesTest, StepHasItsHeight) {
  const auto patch = Patch(0.1, 0.3, [](double x, double) { return x > 0.05 ? 0.17 : 0.0; });
  const TerrainFeatures f = ComputeFeatures(patch);
  EXPECT_NEAR(f.step, 0.17, 1e-12);
  EXPECT_GT(f.roughness, 0.01);
  // 0.17 m exceeds the default 0.15 m critical step: non-traversable.
  EXPECT_EQ(TraversabilityValue(f, MapParams{}), 1.0);
}

TEST(TerrainFeaturesTest, RoughnessIsTheResidualToThePlane) {
  // Checkerboard +-2 cm around a plane: RMS residual ~2 cm, orthogonal to a flat plane.
  const auto patch = Patch(0.1, 0.3, [](double x, double y) {
    const int parity =
        (static_cast<int>(std::lround(x * 10)) + static_cast<int>(std::lround(y * 10))) & 1;
    return parity ? 0.02 : -0.02;
  });
  const TerrainFeatures f = ComputeFeatures(patch);
  EXPECT_NEAR(f.roughness, 0.02, 2e-3);
  EXPECT_NEAR(f.step, 0.04, 1e-12);
}

TEST(TerrainFeaturesTest, ValueCombinesWeightedCriteria) {
  MapParams p;  // weights 0.4, 0.4, 0.2; crit 0.15 m, 20 deg, 0.05 m
  const TerrainFeatures f{0.075, 10.0, 0.025};
  EXPECT_NEAR(TraversabilityValue(f, p), 0.4 * 0.5 + 0.4 * 0.5 + 0.2 * 0.5, 1e-12);
  EXPECT_EQ(TraversabilityValue({0.0, 21.0, 0.0}, p), 1.0);  // slope beyond critical
  EXPECT_EQ(TraversabilityValue({0.0, 0.0, 0.06}, p), 1.0);  // roughness beyond critical
}

TEST(TerrainFeaturesTest, PoseNoiseDiscountsStepAndRoughnessOnly) {
  const TerrainFeatures f{0.1, 5.0, 0.03};
  // Off: the same features, bit for bit.
  const TerrainFeatures off = DiscountPoseNoise(f, 0.0);
  EXPECT_EQ(off.step, f.step);
  EXPECT_EQ(off.slope_deg, f.slope_deg);
  EXPECT_EQ(off.roughness, f.roughness);
  // 2 cm per scan: the step less 2 sqrt(2) x 2 cm, the roughness less 2 cm in quadrature.
  const TerrainFeatures d = DiscountPoseNoise(f, 0.02);
  EXPECT_NEAR(d.step, 0.1 - 2 * std::sqrt(2.0) * 0.02, 1e-15);
  EXPECT_NEAR(d.roughness, std::sqrt(0.03 * 0.03 - 0.02 * 0.02), 1e-15);
  EXPECT_EQ(d.slope_deg, f.slope_deg);  // a tilt is not a height error
  EXPECT_EQ(DiscountStep(f.step, 0.02), d.step);
  // What noise alone explains is nothing, never less.
  const TerrainFeatures n = DiscountPoseNoise({0.05, 1.0, 0.01}, 0.03);
  EXPECT_EQ(n.step, 0.0);
  EXPECT_EQ(n.roughness, 0.0);
  // A step beyond the critical one by more than the noise is still an obstacle.
  MapParams p;  // step_crit 0.15 m
  EXPECT_EQ(TraversabilityValue(DiscountPoseNoise({0.25, 0.0, 0.0}, 0.03), p), 1.0);
  EXPECT_LT(TraversabilityValue(DiscountPoseNoise({0.15, 0.0, 0.0}, 0.03), p), 0.2);
}

TEST(DiskOffsetsTest, KeepsCellsExactlyAtTheRadius) {
  const auto offsets = DiskOffsets(0.3, 0.1);  // (0.3/0.1)^2 is 8.999999999999998 in doubles
  EXPECT_EQ(offsets.size(), 29u);
  bool has_edge = false;
  for (const CellIndex& o : offsets) has_edge |= (o.x == 3 && o.y == 0);
  EXPECT_TRUE(has_edge);
}

}  // namespace
}  // namespace bgkmap
