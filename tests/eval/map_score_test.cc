// The state-layer error rates of ScoreMap on hand-made cases: a flat 10 x 10 patch that the map
// calls traversable everywhere, and a 63-degree one it calls traversable nowhere,, against a truth
// that blocks its lower half.
#include "bgkmap/eval/map_score.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {
namespace {

// One point per cell over cells (0..9, 0..9), in the map frame, on the plane z = grade * x.
std::unique_ptr<TerrainMap> Patch(const MapParams& p, double grade) {
  auto map = std::move(TerrainMap::Create(p)).value();
  std::vector<Point3f> points;
  for (int ix = 0; ix < 10; ++ix) {
    for (int iy = 0; iy < 10; ++iy) {
      points.push_back({static_cast<float>((ix + 0.5) * p.resolution),
                        static_cast<float>((iy + 0.5) * p.resolution),
                        static_cast<float>(grade * (ix + 0.5) * p.resolution)});
    }
  }
  EXPECT_TRUE(map->IntegrateScan(points, Pose{}, /*frame_is_map=*/true).ok());
  return map;
}

// Truth over cells (0..11, 0..9): the patch's cells with iy < 5 are non-traversable, the rest
// traversable; columns 10 and 11 are visible in the truth but unknown to the map.
Raster Truth(const TerrainMap& map) {
  CellBox box;
  box.min = {0, 0};
  box.max = {11, 9};
  Raster truth = ExtractRaster(map, box, {Layer::kElevation, Layer::kState});
  std::vector<float>& state = truth.data[1];
  for (int64_t row = 0; row < truth.rows; ++row) {
    for (int64_t col = 0; col < truth.cols; ++col) {
      const int iy = box.max.y - static_cast<int>(row);
      const CellState s = iy < 5 ? CellState::kNonTraversable : CellState::kTraversable;
      state[static_cast<size_t>(row * truth.cols + col)] = static_cast<float>(s);
      truth.data[0][static_cast<size_t>(row * truth.cols + col)] = 0.0f;
    }
  }
  return truth;
}

MapParams Params() {
  MapParams p;
  p.method = Method::kBaseline;  // v = 0 on flat ground, variance 0: no inference to reason about
  return p;
}

TEST(MapScoreTest, AllTraversableMissesEveryBlockedCell) {
  auto map = Patch(Params(), 0.0);
  ASSERT_EQ(map->Estimate({3, 3}).state, CellState::kTraversable);
  const eval::MapScore s = eval::ScoreMap(*map, Truth(*map));
  EXPECT_EQ(s.truth_cells, 120);
  EXPECT_EQ(s.known_cells, 100);
  EXPECT_EQ(s.dangerous_misses, 50);  // iy 0..4 of the patch
  EXPECT_EQ(s.false_alarms, 0);
  EXPECT_DOUBLE_EQ(s.dangerous_miss_rate, 0.5);
  EXPECT_DOUBLE_EQ(s.false_alarm_rate, 0.0);
  EXPECT_DOUBLE_EQ(s.state_accuracy, 0.5);
}

TEST(MapScoreTest, NothingTraversableRaisesEveryFreeCell) {
  auto map = Patch(Params(), 2.0);  // slope atan(2) = 63 deg > slope_crit 20 deg: v = 1
  ASSERT_EQ(map->Estimate({3, 3}).state, CellState::kNonTraversable);
  const eval::MapScore s = eval::ScoreMap(*map, Truth(*map));
  EXPECT_EQ(s.known_cells, 100);
  EXPECT_EQ(s.dangerous_misses, 0);
  EXPECT_EQ(s.false_alarms, 50);  // iy 5..9 of the patch
  EXPECT_DOUBLE_EQ(s.dangerous_miss_rate, 0.0);
  EXPECT_DOUBLE_EQ(s.false_alarm_rate, 0.5);
}

TEST(MapScoreTest, RatesAreUndefinedWithoutKnownCells) {
  auto map = Patch(Params(), 0.0);
  CellBox box;
  box.min = {20, 20};
  box.max = {21, 21};
  Raster truth = ExtractRaster(*map, box, {Layer::kElevation, Layer::kState});
  for (float& v : truth.data[1]) v = static_cast<float>(CellState::kTraversable);
  const eval::MapScore s = eval::ScoreMap(*map, truth);
  EXPECT_EQ(s.truth_cells, 4);
  EXPECT_EQ(s.known_cells, 0);
  EXPECT_TRUE(std::isnan(s.dangerous_miss_rate));
  EXPECT_TRUE(std::isnan(s.false_alarm_rate));
}

}  // namespace
}  // namespace bgkmap
