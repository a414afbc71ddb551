// bgk-obstacle (docs/semantics.md) on hand-computed cases: a one-cell obstacle that the kernel
// spread of one-step averages away is kept, and the state's two-deviation margin.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {
namespace {

constexpr double kRes = 0.1, kL = 0.5;

// The sparse kernel of semantics step 4, written out.
double K(double d) {
  const double u = 2 * std::numbers::pi * d / kL;
  return ((2 + std::cos(u)) / 3) * (1 - d / kL) + std::sin(u) / (2 * std::numbers::pi);
}

MapParams Params(Method method) {
  MapParams p;
  p.method = method;
  p.resolution = kRes;
  p.kernel_length = kL;
  p.robot_radius = kRes;  // v from the cell and its 4 neighbours
  p.min_range = 0;
  return p;
}

// Flat ground at z = 0 over cells -5..5 x -5..5, one point per cell, except a 1 m post at (0,0).
std::unique_ptr<TerrainMap> Post(Method method) {
  auto map = std::move(TerrainMap::Create(Params(method))).value();
  std::vector<Point3f> points;
  for (int ix = -5; ix <= 5; ++ix) {
    for (int iy = -5; iy <= 5; ++iy) {
      points.push_back({static_cast<float>((ix + 0.5) * kRes),
                        static_cast<float>((iy + 0.5) * kRes), ix == 0 && iy == 0 ? 1.0f : 0.0f});
    }
  }
  EXPECT_TRUE(map->IntegrateScan(points, Pose{}, /*frame_is_map=*/true).ok());
  return map;
}

TEST(BgkObstacleTest, AOneCellPostIsKeptWhereOneStepAveragesItAway) {
  // v = 1 at the post and its 4 neighbours (a 1 m step within robot_radius), 0 elsewhere. Every
  // cell within l of the post is observed, so at the post the spread counts are
  // A = k(0) + 4 k(res), B = S - A, with S the kernel's sum over its stencil.
  double S = 0;
  for (int dx = -5; dx <= 5; ++dx) {
    for (int dy = -5; dy <= 5; ++dy) {
      const double d = kRes * std::hypot(dx, dy);
      if (d < kL) S += K(d);
    }
  }
  const double a = K(0) + 4 * K(kRes), b = S - a;
  const MapParams p = Params(Method::kBgkObstacle);
  const double spread_mean = (p.alpha0 + a) / (p.alpha0 + p.beta0 + S);
  ASSERT_LT(spread_mean, 0.5);  // the case is one where spreading loses the post

  const CellEstimate one_step = Post(Method::kOneStep)->Estimate({0, 0});
  EXPECT_NEAR(one_step.traversability, spread_mean, 1e-5);
  EXPECT_EQ(one_step.state, CellState::kTraversable);  // a dangerous miss

  // bgk-obstacle adds the post's own v = 1 with weight S: A = a + S, B = b.
  const CellEstimate kept = Post(Method::kBgkObstacle)->Estimate({0, 0});
  EXPECT_NEAR(kept.traversability, (p.alpha0 + a + S) / (p.alpha0 + p.beta0 + 2 * S), 1e-5);
  EXPECT_GT(kept.traversability, 0.5);
  EXPECT_EQ(kept.state, CellState::kNonTraversable);
  EXPECT_FLOAT_EQ(kept.elevation, 1.0f);  // raw elevation, as one-step: the post's height
  (void)b;
}

TEST(BgkObstacleTest, FlatGroundStaysTraversableAndCoverageIsOneSteps) {
  auto kept = Post(Method::kBgkObstacle);
  auto one_step = Post(Method::kOneStep);
  EXPECT_EQ(kept->CountKnownCells(), one_step->CountKnownCells());
  // (4, 4): its own v = 0 and every v within l is 0 (the post's blocked cells are > l away).
  EXPECT_EQ(kept->Estimate({4, 4}).state, CellState::kTraversable);
  EXPECT_NEAR(kept->Estimate({4, 4}).traversability, 0.0, 1e-3);
}

TEST(BgkObstacleTest, TheMeanMustClearTheThresholdByTwoDeviations) {
  MapParams p = Params(Method::kBgkObstacle);
  p.variance_threshold = 1.0;  // off, as in the experiments: only the margin decides
  MapParams q = p;
  q.method = Method::kOneStep;
  // A = 0.4, B = 0.6: mean 0.4002, variance 0.4010 * 0.6010 / (1.002^2 * 2.002) = 0.1199, sd 0.346.
  EXPECT_EQ(EstimateCell(p, 1, 0, 0, 0.4f, 0.6f).state, CellState::kNonTraversable);
  EXPECT_EQ(EstimateCell(q, 1, 0, 0, 0.4f, 0.6f).state, CellState::kTraversable);
  // A = 40, B = 60: mean 0.4000, sd 0.0487; 0.4000 + 0.0975 < 0.5.
  EXPECT_EQ(EstimateCell(p, 1, 0, 0, 40.0f, 60.0f).state, CellState::kTraversable);
  // A = 45, B = 55: mean 0.45, sd 0.0495; 0.45 + 0.099 > 0.5, one-step still calls it free.
  EXPECT_EQ(EstimateCell(p, 1, 0, 0, 45.0f, 55.0f).state, CellState::kNonTraversable);
  EXPECT_EQ(EstimateCell(q, 1, 0, 0, 45.0f, 55.0f).state, CellState::kTraversable);
}

}  // namespace
}  // namespace bgkmap
