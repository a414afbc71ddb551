// The four methods of the paper's comparison, on the same sparse scans.
#include <gtest/gtest.h>

#include <cmath>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

std::unique_ptr<TerrainMap> BuildSparse(Method method) {
  MapParams p;
  p.method = method;
  auto map = std::move(TerrainMap::Create(p)).value();
  // Sparse scans: 400 points over a 5 m disk (7,850 cells) leave most cells unobserved.
  for (int s = 0; s < 3; ++s) {
    const Eigen::Vector3d origin(0.5 * s, 0, 1.0);
    EXPECT_TRUE(map->IntegrateScan(
                       testing::SampleSurface(testing::RollingWithStep, origin, 5.0, 400, 7 + s),
                       testing::At(origin))
                    .ok());
  }
  return map;
}

int64_t CountWithTraversability(const TerrainMap& map) {
  int64_t n = 0;
  const CellBox box = map.KnownBounds();
  for (int y = box.min.y; y <= box.max.y; ++y) {
    for (int x = box.min.x; x <= box.max.x; ++x) {
      n += std::isnan(map.Estimate({x, y}).traversability) ? 0 : 1;
    }
  }
  return n;
}

TEST(MethodsTest, BaselineKnowsOnlyObservedCells) {
  auto baseline = BuildSparse(Method::kBaseline);
  auto bgk = BuildSparse(Method::kBgkPlus);
  // Observed cells: at most the 1200 points; the kernel spreads BGK far wider.
  EXPECT_LE(baseline->CountKnownCells(), 1200);
  EXPECT_GT(bgk->CountKnownCells(), 3 * baseline->CountKnownCells());
}

TEST(MethodsTest, InferenceCoversMoreThanDirectComputation) {
  const int64_t baseline = CountWithTraversability(*BuildSparse(Method::kBaseline));
  const int64_t bgk_plus = CountWithTraversability(*BuildSparse(Method::kBgkPlus));
  const int64_t bgk_trav = CountWithTraversability(*BuildSparse(Method::kBgkTrav));
  const int64_t one_step = CountWithTraversability(*BuildSparse(Method::kOneStep));
  EXPECT_GT(bgk_plus, 2 * baseline);
  EXPECT_GT(bgk_trav, 2 * baseline);
  EXPECT_GT(one_step, 2 * baseline);
}

TEST(MethodsTest, BgkTravComputesValuesAtEveryKnownCellItTouched) {
  MapParams p;
  p.method = Method::kBgkTrav;
  auto map = std::move(TerrainMap::Create(p)).value();
  const Eigen::Vector3d origin(0, 0, 1.0);
  Result<ScanReport> r = map->IntegrateScan(
      testing::SampleSurface(testing::RollingWithStep, origin, 5.0, 1500, 7), testing::At(origin));
  ASSERT_TRUE(r.ok());
  // Every known cell is within l of an observed cell, and all have >= 3 known neighbours.
  EXPECT_EQ(static_cast<int64_t>(r->feature_cells), map->CountKnownCells());
  EXPECT_GT(r->feature_cells, 3 * r->observed_cells);
}

TEST(MethodsTest, BaselineElevationIsTheRunningMeanOfObservations) {
  MapParams p;
  p.method = Method::kBaseline;
  p.min_range = 0;
  auto map = std::move(TerrainMap::Create(p)).value();
  for (float z : {1.0f, 2.0f, 6.0f}) {
    ASSERT_TRUE(map->IntegrateScan(std::vector<Point3f>{{0.05f, 0.05f, z}}, Pose{}, true).ok());
  }
  EXPECT_FLOAT_EQ(map->Estimate({0, 0}).elevation, 3.0f);
  EXPECT_EQ(map->Estimate({1, 0}).state, CellState::kUnknown);
  EXPECT_EQ(map->CountKnownCells(), 1);
}

TEST(MethodsTest, OneStepSpreadsTraversabilityButNotElevation) {
  auto map = BuildSparse(Method::kOneStep);
  int64_t trav_only = 0;
  const CellBox box = map->KnownBounds();
  for (int y = box.min.y; y <= box.max.y; ++y) {
    for (int x = box.min.x; x <= box.max.x; ++x) {
      const CellEstimate e = map->Estimate({x, y});
      if (e.state != CellState::kUnknown && std::isnan(e.elevation)) ++trav_only;
    }
  }
  EXPECT_GT(trav_only, 1000);
}

}  // namespace
}  // namespace bgkmap
