// Something rose above ground the map knew (docs/semantics.md, "Dynamics", free-space evidence
// step 1): the traversability counts within l of it are re-learnt, and so are those of every
// cell within robot_radius of it, whose v the new object decides. With the defaults (l =
// robot_radius = 0.3 m) the kernel's support stops short of l, so the cells exactly robot_radius
// from the object kept the ground evidence of the scans before it and stayed traversable: a
// robot centred there touches the object.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

const Eigen::Vector3d kSensor(0.05, 0.05, 1.0);

// Flat ground 3-8 m ahead; with `box`, a 0.5 x 1 m box 0.8 m tall at x 5.5-6 m (its shadow
// unseen).
std::vector<Point3f> Scene(bool box) {
  return InSensorFrame(box ? GroundAhead(LaneBox{5.5f, 6.0f, 0.8f}) : GroundAhead(), kSensor);
}

TEST(RisenReachTest, CellsExactlyARobotRadiusFromANewObjectAreBlockedAtOnce) {
  const MapParams p;
  ASSERT_EQ(p.kernel_length, p.robot_radius);
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(map->IntegrateScan(Scene(false), At(kSensor)).ok());
  for (double y = -0.45; y <= 0.46; y += 0.1) {
    ASSERT_EQ(map->EstimateAt(5.25, y).state, CellState::kTraversable) << y;
  }
  ASSERT_TRUE(map->IntegrateScan(Scene(true), At(kSensor)).ok());
  // The box's nearest cells are centred at x = 5.55; x = 5.25 is robot_radius from them.
  for (double y = -0.45; y <= 0.46; y += 0.1) {
    for (double x : {5.25, 5.35, 5.45}) {
      const CellEstimate e = map->EstimateAt(x, y);
      EXPECT_EQ(e.state, CellState::kNonTraversable) << x << ", " << y;
      EXPECT_GE(e.traversability, p.trav_threshold) << x << ", " << y;
    }
  }
  // Farther than robot_radius, the ground evidence the earlier scans gave stands.
  for (double y = -0.45; y <= 0.46; y += 0.1) {
    EXPECT_EQ(map->EstimateAt(5.05, y).state, CellState::kTraversable) << y;
  }
}

TEST(RisenReachTest, TheSameMapWhateverTheTiling) {
  auto build = [](int tile_size) {
    MapParams p;
    p.tile_size = tile_size;
    std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
    for (int k = 0; k < 5; ++k) EXPECT_TRUE(map->IntegrateScan(Scene(false), At(kSensor)).ok());
    EXPECT_TRUE(map->IntegrateScan(Scene(true), At(kSensor)).ok());
    return map;
  };
  const std::unique_ptr<TerrainMap> reference = build(64);
  const CellBox box = reference->KnownBounds();
  for (int tile_size : {8, 9, 20}) {
    const std::unique_ptr<TerrainMap> map = build(tile_size);
    int differing = 0;
    for (int y = box.min.y - 4; y <= box.max.y + 4; ++y) {
      for (int x = box.min.x - 4; x <= box.max.x + 4; ++x) {
        const CellEstimate a = reference->Estimate({x, y}), b = map->Estimate({x, y});
        differing += !(a.state == b.state &&
                       (a.state == CellState::kUnknown ||
                        (a.elevation == b.elevation && a.traversability == b.traversability)));
      }
    }
    EXPECT_EQ(differing, 0) << "tile size " << tile_size;
  }
}

}  // namespace
}  // namespace bgkmap::testing
