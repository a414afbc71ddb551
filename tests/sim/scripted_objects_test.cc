// Boxes of a change script on a world (sim/scripted_objects.h): present exactly from `appear` to
// before `disappear`, standing `height` above the ground at their centre, and inside the height
// bound the ray caster trusts to skip empty spans.
#include "bgkmap/sim/scripted_objects.h"

#include <gtest/gtest.h>

#include <cmath>

#include "bgkmap/sim/ray_caster.h"

namespace bgkmap::sim {
namespace {

// A ramp rising 0.1 m per metre along x.
class Ramp : public World {
 public:
  double SurfaceHeight(double x, double) const override { return 0.1 * x; }
  double MaxHeight() const override { return 10.0; }
  double MaxHeightIn(double, double, double x1, double) const override { return 0.1 * x1; }
};

TEST(ScriptedObjectsTest, BoxesStandOnTheGroundAtTheirCentreOnlyWhilePresent) {
  const auto base = std::make_shared<Ramp>();
  ScriptedObject o;
  o.center_x = 10.0;
  o.size_x = 2.0;
  o.size_y = 1.0;
  o.height = 1.5;
  o.appear = 3;
  o.disappear = 7;
  const std::vector<ScriptedObject> objects = {o};
  for (int k : {0, 2, 7, 9}) {
    EXPECT_DOUBLE_EQ(WorldAtScan(base, objects, k)->SurfaceHeight(10.0, 0.0), 1.0) << k;
  }
  for (int k : {3, 6}) {
    const auto w = WorldAtScan(base, objects, k);
    EXPECT_DOUBLE_EQ(w->SurfaceHeight(10.0, 0.0), 2.5) << k;   // ground 1.0 at the centre + 1.5
    EXPECT_DOUBLE_EQ(w->SurfaceHeight(10.9, 0.4), 2.5) << k;   // flat top
    EXPECT_DOUBLE_EQ(w->SurfaceHeight(11.1, 0.0), 1.11) << k;  // outside: the ramp
    EXPECT_DOUBLE_EQ(w->SurfaceHeight(10.0, 0.6), 1.0) << k;
    EXPECT_GE(w->MaxHeightIn(9.5, -0.1, 9.6, 0.1), 2.5) << k;        // the bound covers the top
    EXPECT_DOUBLE_EQ(w->MaxHeightIn(0.0, 0.0, 5.0, 5.0), 0.5) << k;  // and only where it is
  }
  // No script: the base world itself, so sequences without one are simulated as before.
  EXPECT_EQ(WorldAtScan(base, {}, 5), base);
}

TEST(ScriptedObjectsTest, ALidarSeesTheBoxOfItsScan) {
  const auto base = std::make_shared<Ramp>();
  ScriptedObject o;
  o.center_x = 5.0;
  o.size_x = o.size_y = 2.0;
  o.height = 1.0;
  o.disappear = 1;
  const std::vector<ScriptedObject> objects = {o};
  const Eigen::Vector3d origin(0, 0, 1.5), down_ahead = Eigen::Vector3d(1, 0, -0.1).normalized();
  // With the box the ray stops at its face x = 4; without it, on the ramp near x = 7.5.
  const double with = CastRay(*WorldAtScan(base, objects, 0), origin, down_ahead, 50.0);
  const double without = CastRay(*WorldAtScan(base, objects, 1), origin, down_ahead, 50.0);
  EXPECT_NEAR(with * down_ahead.x(), 4.0, 0.01);
  EXPECT_NEAR(without * down_ahead.x(), 7.5, 0.01);
}

}  // namespace
}  // namespace bgkmap::sim
