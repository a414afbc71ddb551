// The City street as long as the drive asks (bgkmap simulate city --length): found by hand, a
// 840 m drive gave 614 empty scans, every one past the street's 210 m (the sensor inside its
// closing wall).
#include "bgkmap/sim/city_world.h"

#include <gtest/gtest.h>

#include "bgkmap/sim/ray_caster.h"
#include "bgkmap/sim/scenario.h"

namespace bgkmap::sim {
namespace {

TEST(CityWorldTest, TheStreetGoesOnAsFarAsTheDrive) {
  const Scenario s = MakeCityScenario(840.0, 120.0, 120.0);  // a scan every 120 m (a few s)
  ASSERT_GE(s.mapping_poses.size(), 7u);
  for (const Pose& pose : s.mapping_poses) {
    EXPECT_GT(SimulateScan(*s.world, s.beams, pose).size(), 1000u)
        << "an empty scan at y = " << pose.translation.y();
  }
  // Closed at the drive's end as at its start.
  EXPECT_GT(s.world->SurfaceHeight(0.0, 840.0 + 20.0), 5.0);
  EXPECT_LT(s.world->SurfaceHeight(0.0, 840.0 - 1.0), 1.0);
}

TEST(CityWorldTest, AShortDriveKeepsTheStreetOf210Metres) {
  const Scenario s = MakeCityScenario(100.0, 10.0, 10.0);
  EXPECT_LT(s.world->SurfaceHeight(0.0, 200.0), 1.0);  // the street beyond the drive is there
  EXPECT_GT(s.world->SurfaceHeight(0.0, 230.0), 5.0);  // and closed where it always was
}

}  // namespace
}  // namespace bgkmap::sim
