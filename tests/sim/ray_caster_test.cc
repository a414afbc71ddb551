#include "bgkmap/sim/ray_caster.h"

#include <gtest/gtest.h>

#include <cmath>

namespace bgkmap::sim {
namespace {

class FlatWorld : public World {
 public:
  double SurfaceHeight(double, double) const override { return 0.0; }
};

class WallWorld : public World {
 public:
  double SurfaceHeight(double x, double) const override { return x > 10.0 ? 5.0 : 0.0; }
  bool InOverhang(double x, double y, double z) const override {
    return std::abs(x + 5) < 1 && std::abs(y) < 1 && z > 2 && z < 3;
  }
};

TEST(RayCasterTest, BeamModelsHaveTheirSizes) {
  EXPECT_EQ(Vlp16().points_per_revolution(), 28800);
  EXPECT_EQ(Hdl32e().points_per_revolution(), 72000);
  EXPECT_EQ(Os1_128().points_per_revolution(), 131072);
}

TEST(RayCasterTest, DownwardBeamsHitFlatGroundAtTheRightRange) {
  BeamModel beams = Vlp16();
  beams.range_noise_std = 0.0;
  Pose pose;
  pose.translation = {0, 0, 1.0};
  const auto pts = SimulateScan(FlatWorld{}, beams, pose);
  // Only the 7 downward lasers (-15..-3 deg; -1 deg reaches 57 m < 100 m too) return.
  EXPECT_EQ(pts.size(), 8u * 1800u);
  for (const Point3f& p : pts) {
    ASSERT_NEAR(p.z, -1.0, 2e-3);  // ground is 1 m below the sensor
  }
}

TEST(RayCasterTest, WallsAndOverhangsReturnAboveTheGround) {
  BeamModel beams = Vlp16();
  beams.range_noise_std = 0.0;
  Pose pose;
  pose.translation = {0, 0, 1.0};
  const auto pts = SimulateScan(WallWorld{}, beams, pose);
  int wall = 0, canopy = 0;
  for (const Point3f& p : pts) {
    if (std::abs(p.x - 10.0) < 0.01 && p.z > 0) ++wall;
    if (p.x < -3.9 && p.x > -6.1 && p.z > 0.9) ++canopy;
  }
  EXPECT_GT(wall, 100);
  EXPECT_GT(canopy, 10);
}

TEST(RayCasterTest, NoiseIsDeterministicPerSeed) {
  Pose pose;
  pose.translation = {0, 0, 1.0};
  RayCastOptions a, b;
  a.seed = b.seed = 7;
  const auto p1 = SimulateScan(FlatWorld{}, Vlp16(), pose, a);
  const auto p2 = SimulateScan(FlatWorld{}, Vlp16(), pose, b);
  ASSERT_EQ(p1.size(), p2.size());
  EXPECT_EQ(p1[100].x, p2[100].x);
}

}  // namespace
}  // namespace bgkmap::sim
