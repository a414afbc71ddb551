#include "bgkmap/sim/ray_caster.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "bgkmap/sim/dem_world.h"

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

// A hilly 80 x 80 m DEM (1 m cells, a NODATA corner) with rocks and ditches.
DemWorld Hills() {
  HeightGrid g{80, 80, 0.0, 0.0, 1.0, {}};
  for (int r = 0; r < 80; ++r) {
    for (int c = 0; c < 80; ++c) {
      const bool nodata = r < 10 && c < 10;
      g.values.push_back(nodata ? NAN
                                : static_cast<float>(3.0 * std::sin(c / 9.0) * std::cos(r / 13.0)));
    }
  }
  ObstacleOptions o;
  o.xmin = o.ymin = 10;
  o.xmax = o.ymax = 70;
  o.rocks = 60;
  return DemWorld(std::move(g), o);
}

// The plain march the fast caster must agree with: fixed growing steps from the sensor on.
double ReferenceRange(const World& w, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                      double max_range) {
  const auto solid = [&](double t) {
    const Eigen::Vector3d p = o + t * d;
    const double h = w.SurfaceHeight(p.x(), p.y());
    return !std::isnan(h) && p.z() <= h;
  };
  double prev = 0, t = 0.02;
  for (; t <= max_range; prev = t, t += 0.02 + 0.004 * t) {
    if (!solid(t)) continue;
    while (t - prev > 1e-3) {
      const double mid = 0.5 * (prev + t);
      (solid(mid) ? t : prev) = mid;
    }
    return t;
  }
  return NAN;
}

TEST(RayCasterTest, SkippingAboveTheDemBoundGivesThePlainMarchRanges) {
  const DemWorld world = Hills();
  const Eigen::Vector3d origin(40.0, 40.0, world.MaxHeight() + 1.0);
  int beams = 0, hits = 0, differ = 0;
  for (int a = 0; a < 90; ++a) {
    const double az = 2.0 * std::numbers::pi * a / 90;
    for (double el_deg : Hdl32e().elevation_deg) {
      const double el = el_deg * std::numbers::pi / 180.0;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      const double ref = ReferenceRange(world, origin, d, 100.0);
      const double fast = CastRay(world, origin, d, 100.0);
      ++beams;
      hits += !std::isnan(ref);
      // Both bisect the same crossing to 1 mm; only a ray grazing a crest over less than one
      // step may be caught by one sample sequence and not the other.
      if (std::isnan(ref) != std::isnan(fast) || std::abs(ref - fast) > 2e-3) ++differ;
    }
  }
  EXPECT_GT(hits, 1000);
  EXPECT_LE(differ, beams / 500) << differ << " of " << beams;
}

TEST(RayCasterTest, RaysLeavingTheDemOrAboveItReturnNothing) {
  const DemWorld world = Hills();
  Pose pose;
  pose.translation = {-50.0, -50.0, world.MaxHeight() + 1.0};  // outside, looking everywhere
  BeamModel beams = Hdl32e();
  beams.max_range = 30.0;  // never reaches the DEM
  EXPECT_TRUE(SimulateScan(world, beams, pose).empty());
}

}  // namespace
}  // namespace bgkmap::sim
