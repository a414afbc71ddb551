#include "bgkmap/sim/dem_world.h"

#include <gtest/gtest.h>

#include <cmath>

#include "bgkmap/sim/ray_caster.h"

namespace bgkmap::sim {
namespace {

// A 20 x 20 m plane sloping along x (z = 0.1 x) with a 6 x 6 cell NODATA lake in the middle.
HeightGrid LakeGrid() {
  HeightGrid g{20, 20, 0.0, 0.0, 1.0, {}};
  for (int r = 0; r < 20; ++r) {
    for (int c = 0; c < 20; ++c) {
      const bool lake = r >= 7 && r < 13 && c >= 7 && c < 13;
      g.values.push_back(lake ? NAN : 0.1f * (c + 0.5f));
    }
  }
  return g;
}

TEST(DemWorldTest, FillNoDataClosesHolesWithinTheirRim) {
  HeightGrid g = LakeGrid();
  EXPECT_EQ(FillNoData(g), 36);
  for (float v : g.values) {
    ASSERT_FALSE(std::isnan(v));
    EXPECT_GE(v, 0.05f - 1e-6f);
    EXPECT_LE(v, 1.95f + 1e-6f);
  }
  HeightGrid empty{2, 2, 0, 0, 1, {NAN, NAN, NAN, NAN}};
  EXPECT_EQ(FillNoData(empty), 0);
}

TEST(DemWorldTest, AFilledLakeReturnsItsSurfaceNotItsWalls) {
  ObstacleOptions none;
  none.rocks = none.ditches = 0;
  none.xmax = none.ymax = 20;
  HeightGrid open = LakeGrid(), closed = LakeGrid();
  FillNoData(closed);
  const Eigen::Vector3d origin(5.0, 10.0, 5.0);
  const Eigen::Vector3d dir = Eigen::Vector3d(1.0, 0.0, -0.9).normalized();  // into the lake
  const double hole = CastRay(DemWorld(open, none), origin, dir, 50.0);
  const double lake = CastRay(DemWorld(closed, none), origin, dir, 50.0);
  ASSERT_FALSE(std::isnan(lake));
  const Eigen::Vector3d p = origin + lake * dir;
  EXPECT_NEAR(p.z(), DemWorld(closed, none).SurfaceHeight(p.x(), p.y()), 2e-3);
  EXPECT_GT(hole, lake + 0.5);  // the open hole is seen through, to its far wall
}

}  // namespace
}  // namespace bgkmap::sim
