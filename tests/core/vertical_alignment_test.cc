// Vertical alignment of a scan to the map (core/vertical_alignment.h): a robot-side step that
// finds the z offset of its scan against the map, the median over the cells both see.
#include "bgkmap/core/vertical_alignment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

// A prepared scan by hand: `n` cells in a square about the sensor at the origin, each at
// height `y`.
PreparedScan ScanOf(int n, double y) {
  PreparedScan s;
  s.has_sensor = true;
  const int side = static_cast<int>(std::ceil(std::sqrt(n)));
  for (int k = 0; k < n; ++k) s.cells.push_back({{k % side - side / 2, k / side - side / 2}, y});
  return s;
}

// A map that has seen flat ground at z = 0 everywhere, well (ten full observations).
MapHeightLookup FlatMap(const MapParams& p) {
  const float w = static_cast<float>(10 * FullKernelWeight(p));
  return [w](CellIndex) { return MapHeight{0.0f, w}; };
}

MapHeight Unknown() { return {std::numeric_limits<float>::quiet_NaN(), 0.0f}; }

TEST(VerticalAlignmentTest, AScanOffsetFromAFlatMapIsAlignedByItsOffset) {
  const MapParams p;
  const VerticalAlignment a = AlignScanVertically(p, ScanOf(400, 0.07), FlatMap(p));
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAligned);
  EXPECT_EQ(a.cells, 400u);
  EXPECT_NEAR(a.dz, 0.07, 1e-12);
  Pose pose;
  pose.translation.z() = 1.5;
  EXPECT_NEAR(AlignedPose(pose, a).translation.z(), 1.43, 1e-12);
}

TEST(VerticalAlignmentTest, TooFewCellsOrAnEmptyMapGiveNone) {
  const MapParams p;
  const VerticalAlignmentOptions o;
  VerticalAlignment a =
      AlignScanVertically(p, ScanOf(static_cast<int>(o.min_cells) - 1, 0.07), FlatMap(p));
  EXPECT_EQ(a.outcome, AlignmentOutcome::kTooFewCells);
  EXPECT_EQ(a.dz, 0.0);
  EXPECT_NEAR(a.median, 0.07, 1e-12);  // measured, not applied
  a = AlignScanVertically(p, ScanOf(static_cast<int>(o.min_cells), 0.07), FlatMap(p));
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAligned);
  a = AlignScanVertically(p, ScanOf(1000, 0.07), [](CellIndex) { return Unknown(); });
  EXPECT_EQ(a.outcome, AlignmentOutcome::kTooFewCells);
  EXPECT_EQ(a.cells, 0u);
  EXPECT_EQ(a.dz, 0.0);
}

TEST(VerticalAlignmentTest, OutliersDoNotMoveTheMedian) {
  const MapParams p;
  PreparedScan s = ScanOf(600, 0.07);
  // A third of the cells are a car's roof the map does not have, a few a hole.
  for (size_t k = 0; k < 200; ++k) s.cells[3 * k].y = 1.6;
  for (size_t k = 0; k < 50; ++k) s.cells[3 * k + 1].y = -3.0;
  const VerticalAlignment a = AlignScanVertically(p, s, FlatMap(p));
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAligned);
  EXPECT_NEAR(a.dz, 0.07, 1e-12);
}

TEST(VerticalAlignmentTest, OnlyCellsNearTheSensorWhereTheMapHasAnObservation) {
  const MapParams p;  // 0.1 m cells
  PreparedScan s = ScanOf(400, 0.07);
  s.sensor_x = 100.0;  // every cell is 100 m away: none within radius_m
  EXPECT_EQ(AlignScanVertically(p, s, FlatMap(p)).cells, 0u);
  s.sensor_x = 0.0;
  // Half the cells at 0.5 m where the map has less than one full observation: not compared.
  for (size_t k = 0; k < 200; ++k) s.cells[2 * k].y = 0.5;
  const float k_full = static_cast<float>(FullKernelWeight(p));
  const MapHeightLookup thin = [&](CellIndex c) {
    const bool even = (c.x + 10) % 2 == 0;  // ScanOf's cell k is (k % 20 - 10, k / 20 - 10)
    return MapHeight{0.0f, even ? 0.9f * k_full : k_full};
  };
  const VerticalAlignment a = AlignScanVertically(p, s, thin);
  EXPECT_EQ(a.cells, 200u);
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAligned);
  EXPECT_NEAR(a.dz, 0.07, 1e-12);  // with the thin cells it would be (0.07 + 0.5) / 2
}

// A wall's cell holds the highest return of each scan, higher as the robot comes nearer: only
// the cells the map calls traversable (flat ground) are compared.
TEST(VerticalAlignmentTest, OnlyCellsTheMapCallsTraversable) {
  const MapParams p;
  PreparedScan s = ScanOf(800, 0.07);
  for (size_t k = 0; k < 400; ++k) s.cells[2 * k].y = 0.3;  // wall cells seen 30 cm higher
  const float w = static_cast<float>(10 * FullKernelWeight(p));
  const MapHeightLookup walls = [&](CellIndex c) {
    const int side = 29;  // ScanOf(800): cell k is (k % 29 - 14, k / 29 - 14)
    const int k = (c.x + side / 2) + side * (c.y + side / 2);
    return MapHeight{0.0f, w, k % 2 == 1};
  };
  VerticalAlignment a = AlignScanVertically(p, s, walls);
  EXPECT_EQ(a.cells, 400u);
  EXPECT_NEAR(a.dz, 0.07, 1e-12);
  VerticalAlignmentOptions every_cell;
  every_cell.traversable_only = false;
  a = AlignScanVertically(p, s, walls, every_cell);
  EXPECT_EQ(a.cells, 800u);
  EXPECT_NEAR(a.dz, (0.07 + 0.3) / 2, 1e-12);
}

TEST(VerticalAlignmentTest, AnOffsetBeyondTheBoundOrNoSensorGivesNone) {
  const MapParams p;
  VerticalAlignment a = AlignScanVertically(p, ScanOf(400, 1.2), FlatMap(p));
  EXPECT_EQ(a.outcome, AlignmentOutcome::kBeyondBound);
  EXPECT_EQ(a.dz, 0.0);
  EXPECT_NEAR(a.median, 1.2, 1e-12);
  PreparedScan cloud = ScanOf(400, 0.07);
  cloud.has_sensor = false;
  EXPECT_EQ(AlignScanVertically(p, cloud, FlatMap(p)).outcome, AlignmentOutcome::kNoSensor);
}

// Experimental (max_tilt_deg > 0): a scan tilted against a flat map is levelled about its sensor.
TEST(VerticalAlignmentTest, ATiltedScanIsLevelledAboutTheSensor) {
  const MapParams p;  // 0.1 m cells
  const double gx = std::tan(0.2 * M_PI / 180), gy = -std::tan(0.1 * M_PI / 180);
  PreparedScan s;
  s.has_sensor = true;
  s.sensor_x = 0.05;
  s.sensor_y = 0.05;
  for (int x = -150; x < 150; x += 3) {
    for (int y = -150; y < 150; y += 3) {
      const double dx = (x + 0.5) * 0.1 - s.sensor_x, dy = (y + 0.5) * 0.1 - s.sensor_y;
      s.cells.push_back({{x, y}, 0.05 + gx * dx + gy * dy});
    }
  }
  VerticalAlignment a = AlignScanVertically(p, s, FlatMap(p));  // the offset alone
  EXPECT_EQ(a.slope_x, 0.0);
  VerticalAlignmentOptions tilt;
  tilt.max_tilt_deg = 1.0;
  a = AlignScanVertically(p, s, FlatMap(p), tilt);
  ASSERT_EQ(a.outcome, AlignmentOutcome::kAligned);
  EXPECT_NEAR(a.slope_x, gx, 1e-9);
  EXPECT_NEAR(a.slope_y, gy, 1e-9);
  EXPECT_NEAR(a.dz, 0.05, 1e-9);
  // The aligned pose puts a point 10 m out in x and 5 m in y back on the map's ground.
  Pose pose;
  pose.translation = Eigen::Vector3d(s.sensor_x, s.sensor_y, 1.5);
  const Eigen::Vector3d seen(10.0, 5.0, 0.05 + gx * 10.0 + gy * 5.0 - 1.5);  // sensor frame
  const Pose level = AlignedPose(pose, a);
  EXPECT_NEAR((level.rotation * seen + level.translation).z(), 0.0, 1e-4);
  // A slope beyond the bound is not taken: the offset alone.
  tilt.max_tilt_deg = 0.15;
  a = AlignScanVertically(p, s, FlatMap(p), tilt);
  EXPECT_EQ(a.slope_x, 0.0);
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAligned);
}

// Through the engine: a scan whose pose is 7 cm too high against a map of the same ground,
// aligned, integrates as the scan without the error.
TEST(VerticalAlignmentTest, ARealScanWithAZErrorAlignsToTheMap) {
  const MapParams p;
  const Eigen::Vector3d sensor(0.05, 0.05, 1.0);
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  ASSERT_TRUE(
      map->IntegrateScan(SampleSurface(RollingWithStep, sensor, 8.0, 60000, 1), At(sensor)).ok());
  const std::vector<Point3f> second = SampleSurface(RollingWithStep, sensor, 8.0, 60000, 2);
  Pose wrong = At(sensor);
  wrong.translation.z() += 0.07;  // the points stay where the sensor saw them
  const PreparedScan prepared = PrepareScan(p, second, wrong).value();
  const VerticalAlignment a = AlignScanVertically(p, prepared, MapHeightsOf(*map));
  ASSERT_EQ(a.outcome, AlignmentOutcome::kAligned);
  EXPECT_NEAR(a.dz, 0.07, 0.005);
  const Pose aligned = AlignedPose(wrong, a);
  EXPECT_NEAR(aligned.translation.z(), sensor.z(), 0.005);
}

}  // namespace
}  // namespace bgkmap::testing
