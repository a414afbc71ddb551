// The robot stands on its footprint (docs/semantics.md, "Dynamics"): with sensor_height > 0 each
// scan's pose is evidence of traversable ground sensor_height below the sensor, within
// robot_radius, weighted footprint_weight at each cell, so real returns win.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

double Flat(double, double) { return 0.0; }

MapParams FootprintParams(double sensor_height) {
  MapParams p;  // dynamics on
  p.sensor_height = sensor_height;
  p.min_range = 2.0;  // the robot's body hides the ground around it from its lidar
  return p;
}

std::unique_ptr<TerrainMap> OneScan(const MapParams& p, const Eigen::Vector3d& sensor,
                                    const std::vector<Point3f>& points) {
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  EXPECT_TRUE(map->IntegrateScan(points, At(sensor)).ok());
  return map;
}

TEST(FootprintPriorTest, PreparedOnlyWithASensorHeightDynamicsAndASensor) {
  const Eigen::Vector3d sensor(0.05, 0.05, 1.0);
  const std::vector<Point3f> pts = SampleSurface(Flat, sensor, 6.0, 2000, 1);
  Result<PreparedScan> off = PrepareScan(FootprintParams(0.0), pts, At(sensor));
  ASSERT_TRUE(off.ok());
  EXPECT_TRUE(off->footprint_cells.empty());
  MapParams paper = FootprintParams(1.0);
  paper.dynamics = Dynamics::kOff;
  EXPECT_TRUE(PrepareScan(paper, pts, At(sensor))->footprint_cells.empty());
  EXPECT_TRUE(PrepareScan(FootprintParams(1.0), pts, Pose{}, /*frame_is_map=*/true)
                  ->footprint_cells.empty());
  Result<PreparedScan> on = PrepareScan(FootprintParams(1.0), pts, At(sensor));
  ASSERT_TRUE(on.ok());
  // robot_radius 0.3 m around a cell centre at 0.1 m cells: offsets within 3 cells, inclusive.
  EXPECT_EQ(on->footprint_cells.size(), 29u);
  EXPECT_DOUBLE_EQ(on->footprint_y, 0.0);
  EXPECT_TRUE(std::is_sorted(on->footprint_cells.begin(), on->footprint_cells.end()));
}

TEST(FootprintPriorTest, TheGroundUnderTheRobotIsKnownAndTraversable) {
  const Eigen::Vector3d sensor(0.05, 0.05, 1.0);
  const std::vector<Point3f> pts = SampleSurface(Flat, sensor, 6.0, 4000, 2);
  // Without it the lidar leaves a hole of min_range under the robot.
  EXPECT_EQ(OneScan(FootprintParams(0.0), sensor, pts)->EstimateAt(0.05, 0.05).state,
            CellState::kUnknown);
  const std::unique_ptr<TerrainMap> map = OneScan(FootprintParams(1.0), sensor, pts);
  for (double dx : {-0.25, 0.0, 0.25}) {
    const CellEstimate e = map->EstimateAt(0.05 + dx, 0.05);
    EXPECT_EQ(e.state, CellState::kTraversable) << dx;
    EXPECT_NEAR(e.elevation, 0.0, 1e-6) << dx;
    EXPECT_NEAR(e.elevation_weight, 0.1, 1e-6) << dx;  // footprint_weight of one observation
  }
  // Beyond robot_radius, the hole stays.
  EXPECT_EQ(map->EstimateAt(0.55, 0.05).state, CellState::kUnknown);
}

TEST(FootprintPriorTest, ARealReturnOutweighsTheFootprint) {
  // A misconfigured sensor_height says 0.0; a return under the robot (min_range 0) says 0.5.
  MapParams p = FootprintParams(1.5);
  p.min_range = 0.0;
  const Eigen::Vector3d sensor(0.05, 0.05, 1.5);
  const std::vector<Point3f> pts = {{0.0f, 0.0f, -1.0f}};  // at (0.05, 0.05, 0.5)
  const CellEstimate e = OneScan(p, sensor, pts)->EstimateAt(0.05, 0.05);
  // (1 x 0.5 + 0.1 x 0.0) / 1.1
  EXPECT_NEAR(e.elevation, 0.5 / 1.1, 1e-6);
  EXPECT_NEAR(e.elevation, 0.5, 0.05);
}

TEST(FootprintPriorTest, DynamicsOffIsThePapersMapBitForBit) {
  MapParams with = FootprintParams(1.0), without = FootprintParams(0.0);
  with.dynamics = without.dynamics = Dynamics::kOff;
  std::unique_ptr<TerrainMap> a = TerrainMap::Create(with).value();
  std::unique_ptr<TerrainMap> b = TerrainMap::Create(without).value();
  for (int k = 0; k < 5; ++k) {
    const Eigen::Vector3d sensor(0.3 * k, 0.1 * k, 1.0);
    const std::vector<Point3f> pts = SampleSurface(RollingWithStep, sensor, 5.0, 3000, 10 + k);
    ASSERT_TRUE(a->IntegrateScan(pts, At(sensor)).ok());
    ASSERT_TRUE(b->IntegrateScan(pts, At(sensor)).ok());
  }
  ASSERT_EQ(a->tile_count(), b->tile_count());
  a->ForEachTile([&](TileKey k, const Tile& t) {
    ASSERT_NE(b->FindTile(k), nullptr);
    EXPECT_TRUE(t == *b->FindTile(k));
  });
}

TEST(FootprintPriorTest, DoesNotDependOnTheTiling) {
  std::unique_ptr<TerrainMap> maps[2];
  const int sizes[2] = {8, 64};
  for (int m = 0; m < 2; ++m) {
    MapParams p = FootprintParams(1.0);
    p.tile_size = sizes[m];
    maps[m] = TerrainMap::Create(p).value();
    for (int k = 0; k < 6; ++k) {
      // Drives across tile borders (0.8 m tiles at size 8).
      const Eigen::Vector3d sensor(-0.6 + 0.37 * k, 0.75,
                                   1.0 + RollingWithStep(-0.6 + 0.37 * k, 0.75));
      const std::vector<Point3f> pts = SampleSurface(RollingWithStep, sensor, 5.0, 3000, 20 + k);
      ASSERT_TRUE(maps[m]->IntegrateScan(pts, At(sensor)).ok());
    }
  }
  int compared = 0;
  for (int x = -20; x <= 30; ++x) {
    for (int y = -10; y <= 25; ++y) {
      const CellEstimate a = maps[0]->Estimate({x, y}), b = maps[1]->Estimate({x, y});
      for (Layer l : {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability,
                      Layer::kTraversabilityVariance, Layer::kState}) {
        const float va = a.Get(l), vb = b.Get(l);
        ASSERT_EQ(std::memcmp(&va, &vb, sizeof va), 0) << x << "," << y;
      }
      compared += a.state != CellState::kUnknown;
    }
  }
  EXPECT_GT(compared, 1000);
}

// P6 (docs/semantics.md, "Dynamics"): the footprint as the vehicle's box, turned to the
// sensor's heading, the sensor off its centre. Catches: the box not turned (yaw ignored), the
// offset applied with the wrong sign or frame, the disk used instead.
TEST(FootprintPriorTest, TheBoxCoversTheVehicleTurnedToItsHeading) {
  MapParams p = FootprintParams(1.0);
  p.footprint_length = 2.0;
  p.footprint_width = 1.0;
  p.footprint_sensor_x = 0.5;  // the sensor 0.5 m ahead of the box's centre
  Pose T = At(Eigen::Vector3d(0.0, 0.0, 1.0));
  T.rotation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Result<PreparedScan> scan = PrepareScan(p, {}, T);
  ASSERT_TRUE(scan.ok());
  // Heading north: the box spans x in [-0.5, 0.5], y in [-1.5, 0.5]; 10 x 20 cell centres.
  const std::vector<CellIndex>& cells = scan->footprint_cells;
  EXPECT_EQ(cells.size(), 200u);
  auto has = [&](int x, int y) {
    return std::binary_search(cells.begin(), cells.end(), CellIndex{x, y});
  };
  EXPECT_TRUE(has(-5, -15) && has(4, -15) && has(-5, 4) && has(4, 4));
  EXPECT_FALSE(has(-6, 0) || has(5, 0) || has(0, -16) || has(0, 5));
  EXPECT_TRUE(scan->footprint_box);
  EXPECT_DOUBLE_EQ(scan->footprint_y, 0.0);
}

// The robot stands on its box: obstacle evidence learnt there (here set by hand: a vehicle that
// drove off) is cleared and the cell is traversable; the disk of robot_radius keeps it (the old
// rule). Catches: A not cleared, cleared outside the box, or cleared by the disk too.
TEST(FootprintPriorTest, TheBoxClearsObstacleEvidenceUnderTheRobot) {
  for (const bool box : {false, true}) {
    MapParams p = FootprintParams(1.0);
    if (box) p.footprint_length = 1.0, p.footprint_width = 1.0;
    std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
    const GridGeometry& g = map->geometry();
    for (const CellIndex c : {CellIndex{0, 0}, CellIndex{9, 0}}) {  // under the robot; 0.9 m off
      Tile& t = map->GetOrCreateTile(g.TileOf(c));
      const int i = g.LocalIndex(c);
      t.w()[i] = 1.0;
      t.a()[i] = 5.0f;  // evidence of an obstacle
    }
    ASSERT_TRUE(map->IntegrateScan({}, At(Eigen::Vector3d(0.05, 0.05, 1.0))).ok());
    const Tile& t = *map->FindTile(g.TileOf({0, 0}));
    EXPECT_EQ(t.a()[g.LocalIndex({0, 0})], box ? 0.0f : 5.0f) << box;
    EXPECT_EQ(map->Estimate({0, 0}).state,
              box ? CellState::kTraversable : CellState::kNonTraversable)
        << box;
    EXPECT_EQ(t.a()[g.LocalIndex({9, 0})], 5.0f) << box;  // outside both footprints
  }
}

// A box needs both edges; one alone leaves the disk of robot_radius (29 cells).
TEST(FootprintPriorTest, ABoxNeedsBothEdges) {
  MapParams p = FootprintParams(1.0);
  p.footprint_length = 4.0;
  ASSERT_TRUE(p.Validate().ok());
  Result<PreparedScan> disk = PrepareScan(p, {}, At(Eigen::Vector3d(0.05, 0.05, 1.0)));
  EXPECT_EQ(disk->footprint_cells.size(), 29u);
  EXPECT_FALSE(disk->footprint_box);
  p.footprint_length = 25.0;
  EXPECT_FALSE(p.Validate().ok());
  p.footprint_length = 4.0;
  p.footprint_sensor_x = -25.0;
  EXPECT_FALSE(p.Validate().ok());
}

}  // namespace
}  // namespace bgkmap::testing
