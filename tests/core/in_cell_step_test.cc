// A step inside a cell (docs/semantics.md, step 6): with dynamics on, a cell whose own points in
// one scan span more height than a critical step on a critical slope across the cell is a face,
// v = 1, whatever its neighbours say; the paper's map (dynamics off) does not look.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "bgkmap/core/terrain_features.h"
#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

const Eigen::Vector3d kSensor(0.05, 0.05, 1.0);

CellState StateAfterOneScan(const MapParams& p, const std::vector<Point3f>& map_frame_points,
                            double x, double y) {
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  EXPECT_TRUE(map->IntegrateScan(InSensorFrame(map_frame_points, kSensor), At(kSensor)).ok());
  return map->EstimateAt(x, y).state;
}

// Every cell of the 2 x 2 m square 4-6 m ahead holds two points, `extent` apart in height.
std::vector<Point3f> TwoLevelPatch(float extent) {
  std::vector<Point3f> pts;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      const float x = 4.05f + 0.1f * i, y = -0.95f + 0.1f * j;
      pts.push_back({x, y, 0.0f});
      pts.push_back({x, y, extent});
    }
  }
  return pts;
}

TEST(InCellStepTest, TheLimitIsACriticalStepPlusACriticalSlopeAcrossTheCell) {
  MapParams p;
  EXPECT_NEAR(InCellStepLimit(p), 0.15 + 0.1 * std::sqrt(2.0) * std::tan(20.0 * M_PI / 180.0),
              1e-12);
  p.resolution = 0.5;  // coarser cells hold more of a slope
  EXPECT_NEAR(InCellStepLimit(p), 0.15 + 0.5 * std::sqrt(2.0) * std::tan(20.0 * M_PI / 180.0),
              1e-12);
}

TEST(InCellStepTest, CellsSpanningMoreThanTheLimitAreFacesBelowItGround) {
  const MapParams p;  // dynamics on; the limit is 0.2015 m
  // Each patch is flat at its top (the cells' maxima): only the span inside the cells differs.
  EXPECT_EQ(StateAfterOneScan(p, TwoLevelPatch(0.19f), 5.05, 0.05), CellState::kTraversable);
  EXPECT_EQ(StateAfterOneScan(p, TwoLevelPatch(0.22f), 5.05, 0.05), CellState::kNonTraversable);
}

TEST(InCellStepTest, TheFaceOfAVehicleOverGroundTheMapForgotIsAnObstacleAtOnce) {
  // Only a vertical face is seen (the ground in front of it is unknown): its cells' neighbours
  // are each other, all at the face's top, which reads as flat ground 1.2 m up.
  std::vector<Point3f> face;
  for (int k = 0; k < 50; ++k) {
    for (int j = 0; j < 10; ++j) face.push_back({5.05f, -0.49f + 0.02f * k, 0.3f + 0.1f * j});
  }
  for (double y : {-0.35, -0.15, 0.05, 0.25, 0.45}) {
    EXPECT_EQ(StateAfterOneScan(MapParams{}, face, 5.05, y), CellState::kNonTraversable) << y;
  }
}

TEST(InCellStepTest, ThePapersMapDoesNotLookInsideCells) {
  MapParams paper;
  paper.dynamics = Dynamics::kOff;
  EXPECT_EQ(StateAfterOneScan(paper, TwoLevelPatch(0.5f), 5.05, 0.05), CellState::kTraversable);
}

}  // namespace
}  // namespace bgkmap::testing
