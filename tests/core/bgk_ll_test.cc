// bgk-ll (docs/semantics.md) on hand-computed cases: the local plane reproduces a plane exactly
// where the kernel mean bends it, agrees with a brute-force weighted least squares, has no slope
// where the data give none, and keeps a step that the kernel mean blurs.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {
namespace {

constexpr double kRes = 0.1, kL = 0.35;

// The sparse kernel of semantics step 4, written out.
double K(double d) {
  if (d >= kL) return 0.0;
  const double u = 2 * std::numbers::pi * d / kL;
  return ((2 + std::cos(u)) / 3) * (1 - d / kL) + std::sin(u) / (2 * std::numbers::pi);
}

MapParams Params(Method method, Dynamics dynamics = Dynamics::kOff) {
  MapParams p;
  p.method = method;
  p.dynamics = dynamics;
  p.resolution = kRes;
  p.kernel_length = kL;
  p.min_range = 0;
  p.max_height_above_sensor = 100;
  return p;
}

using Height = std::function<double(int, int)>;  // cell (ix, iy) -> observed height

// One point at the centre of every cell (ix, iy) with keep(ix, iy), at height(ix, iy).
std::unique_ptr<TerrainMap> Observe(const MapParams& p, const Height& height,
                                    const std::function<bool(int, int)>& keep, int half = 6) {
  auto map = std::move(TerrainMap::Create(p)).value();
  std::vector<Point3f> points;
  for (int ix = -half; ix <= half; ++ix) {
    for (int iy = -half; iy <= half; ++iy) {
      if (!keep(ix, iy)) continue;
      points.push_back({static_cast<float>((ix + 0.5) * kRes),
                        static_cast<float>((iy + 0.5) * kRes), static_cast<float>(height(ix, iy))});
    }
  }
  EXPECT_TRUE(map->IntegrateScan(points, Pose{}, /*frame_is_map=*/true).ok());
  return map;
}

// bgk-ll's elevation at (cx, cy), brute force: the intercept of the weighted least-squares plane
// through the observed cells within l (the cell itself included, k(0) = 1), solved with Eigen:
// the oracle bgk-ll's moments must agree with.
double OracleIntercept(int cx, int cy, const Height& height,
                       const std::function<bool(int, int)>& keep) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  const int r = static_cast<int>(std::ceil(kL / kRes));
  for (int dx = -r; dx <= r; ++dx) {
    for (int dy = -r; dy <= r; ++dy) {
      if (!keep(cx + dx, cy + dy)) continue;
      const double k = K(kRes * std::hypot(dx, dy));
      if (k <= 0) continue;
      const Eigen::Vector3d x(1, dx * kRes, dy * kRes);
      a += k * x * x.transpose();
      b += k * static_cast<double>(static_cast<float>(height(cx + dx, cy + dy))) * x;
    }
  }
  return a.ldlt().solve(b)(0);
}

double Plane(int ix, int iy) { return 0.1 + 0.3 * (ix + 0.5) * kRes - 0.2 * (iy + 0.5) * kRes; }

// A disk of radius 5 cells with a hole around (2, 1): unobserved cells inside, and an edge.
bool DiskWithHole(int ix, int iy) {
  return ix * ix + iy * iy <= 25 && std::hypot(ix - 2, iy - 1) > 1.2;
}

// Mutations: the elevation read as the kernel mean (S / W); the slopes' sign flipped in the
// intercept; the moments' u and v swapped in the stencil.
TEST(BgkLlTest, APlaneIsReproducedExactlyWhereTheKernelMeanBendsIt) {
  for (Dynamics dynamics : {Dynamics::kOff, Dynamics::kOn}) {
    auto ll = Observe(Params(Method::kBgkLocalLinear, dynamics), Plane, DiskWithHole);
    auto nw = Observe(Params(Method::kBgkPlus, dynamics), Plane, DiskWithHole);
    double worst_ll = 0, worst_nw = 0;
    int known = 0;
    for (int ix = -8; ix <= 8; ++ix) {
      for (int iy = -8; iy <= 8; ++iy) {
        // The disk, its hole and one ring beyond its edge: cells whose neighbourhood spreads in
        // both directions. Further out, l reaches only a sliver of the edge, and the slope
        // across it is left at 0 (NoSlopeWhereTheDataGiveNone).
        if (ix * ix + iy * iy > 36) continue;
        const CellEstimate e = ll->Estimate({ix, iy});
        if (std::isnan(e.elevation)) continue;
        ++known;
        // Exact up to the float heights of the points and the float elevation layer.
        worst_ll = std::max(worst_ll, std::abs(e.elevation - Plane(ix, iy)));
        worst_nw = std::max(worst_nw, std::abs(nw->Estimate({ix, iy}).elevation - Plane(ix, iy)));
      }
    }
    EXPECT_GT(known, 100);
    EXPECT_LT(worst_ll, 2e-6);
    EXPECT_GT(worst_nw, 0.01);  // the kernel mean at the edge: biased towards the interior
  }
}

// The elevation variance carries the extrapolation: sigma2 (1 / W + c' C^-1 c), c the training
// cells' centroid. Inside the disk it is close to the kernel mean's sigma2 / W; at the rim,
// where all the data lie on one side, it is several times larger. Mutation: leverage left out
// (the rim's variance equals sigma2 / W).
TEST(BgkLlTest, ExtrapolatedCellsAreLessCertain) {
  const MapParams p = Params(Method::kBgkLocalLinear);
  auto ll = Observe(p, Plane, DiskWithHole);
  auto nw = Observe(Params(Method::kBgkPlus), Plane, DiskWithHole);
  const CellEstimate inside = ll->Estimate({-2, -2}), rim = ll->Estimate({6, 0});
  ASSERT_FALSE(std::isnan(rim.elevation));
  EXPECT_NEAR(inside.elevation_variance, nw->Estimate({-2, -2}).elevation_variance,
              0.05 * inside.elevation_variance);
  EXPECT_GT(rim.elevation_variance, 3 * nw->Estimate({6, 0}).elevation_variance);
}

TEST(BgkLlTest, AgreesWithABruteForceWeightedPlaneFit) {
  // Not a plane: a bump, so the fit depends on every weight.
  const Height bumpy = [](int ix, int iy) { return 0.05 * std::sin(ix * 0.9) + 0.02 * iy * iy; };
  auto map = Observe(Params(Method::kBgkLocalLinear), bumpy, DiskWithHole);
  int checked = 0;
  // The hole, the rim beyond the edge (unobserved: a plane fit), observed cells (their own).
  for (auto [cx, cy] : {std::pair{2, 1}, {2, 2}, {6, 0}, {0, -6}, {4, 4}, {0, 0}, {-3, 4}}) {
    const double oracle = OracleIntercept(cx, cy, bumpy, DiskWithHole);
    EXPECT_NEAR(map->Estimate({cx, cy}).elevation, oracle, 2e-6) << cx << ", " << cy;
    ++checked;
  }
  EXPECT_EQ(checked, 7);
}

TEST(BgkLlTest, NoSlopeWhereTheDataGiveNone) {
  // One observed cell: every cell within l reads its height.
  auto one = Observe(Params(Method::kBgkLocalLinear), Plane,
                     [](int ix, int iy) { return ix == 0 && iy == 0; });
  EXPECT_FLOAT_EQ(one->Estimate({1, 1}).elevation, static_cast<float>(Plane(0, 0)));
  EXPECT_FLOAT_EQ(one->Estimate({-2, 0}).elevation, static_cast<float>(Plane(0, 0)));
  // One observed row (iy = 0) on the plane: off the row, the height is the row's at that x (its
  // slope along x kept, none across it).
  auto row = Observe(Params(Method::kBgkLocalLinear), Plane, [](int, int iy) { return iy == 0; });
  for (int ix = -3; ix <= 3; ++ix) {
    EXPECT_NEAR(row->Estimate({ix, 2}).elevation, Plane(ix, 0), 2e-6) << ix;
    EXPECT_NEAR(row->Estimate({ix, -1}).elevation, Plane(ix, 0), 2e-6) << ix;
  }
}

// A 0.3 m step along x = 0 (cells ix >= 0 high), every cell observed once. The elevation is the
// plane fit (a smoother: it ramps over the step like any kernel estimate), but v is computed
// from the observed heights, so the step is kept where it decides traversability: bgk-ll's
// traversability is one-step's (raw heights) exactly, cell for cell, and the step's cells are
// non-traversable on both sides. Mutation: v from the kernel mean S / W instead of the observed
// heights (FeatureHeight and ValueAt's fast path) -> the traversability differs from one-step's.
TEST(BgkLlTest, AStepIsKeptInTraversability) {
  const Height step = [](int ix, int) { return ix >= 0 ? 0.3 : 0.0; };
  const auto all = [](int ix, int iy) { return std::abs(ix) <= 6 && std::abs(iy) <= 6; };
  auto ll = Observe(Params(Method::kBgkLocalLinear), step, all);
  auto raw = Observe(Params(Method::kOneStep), step, all);
  auto nw = Observe(Params(Method::kBgkPlus), step, all);
  int compared = 0, differs_from_bgk_plus = 0;
  for (int ix = -6; ix <= 6; ++ix) {
    for (int iy = -6; iy <= 6; ++iy) {
      EXPECT_NEAR(ll->Estimate({ix, iy}).elevation, OracleIntercept(ix, iy, step, all), 2e-6)
          << ix << ", " << iy;
      const float t = ll->Estimate({ix, iy}).traversability;
      EXPECT_EQ(t, raw->Estimate({ix, iy}).traversability) << ix << ", " << iy;
      differs_from_bgk_plus += t != nw->Estimate({ix, iy}).traversability;
      ++compared;
    }
  }
  EXPECT_EQ(compared, 169);
  EXPECT_GT(differs_from_bgk_plus, 20);
  for (int ix : {-1, 0}) {
    EXPECT_EQ(ll->Estimate({ix, 0}).state, CellState::kNonTraversable) << ix;
    EXPECT_GT(ll->Estimate({ix, 0}).traversability, 0.9f) << ix;
  }
  // Far from the step (more than robot radius + l): flat, traversable.
  EXPECT_EQ(ll->Estimate({-6, 0}).state, CellState::kTraversable);
  EXPECT_EQ(ll->Estimate({6, 0}).state, CellState::kTraversable);
}

// Two scans merged equal one map that saw both (additive moments), bitwise.
TEST(BgkLlTest, MapsOfTwoHalvesMergeIntoTheMapOfBoth) {
  const MapParams p = Params(Method::kBgkLocalLinear, Dynamics::kOff);
  auto left = Observe(p, Plane, [](int ix, int) { return ix < 1; });
  auto right = Observe(p, Plane, [](int ix, int) { return ix >= 1; });
  auto both = std::move(TerrainMap::Create(p)).value();
  left->ForEachTile([&](TileKey k, const Tile& t) { both->AddTile(k, t); });
  right->ForEachTile([&](TileKey k, const Tile& t) { both->AddTile(k, t); });
  int compared = 0;
  for (int ix = -8; ix <= 8; ++ix) {
    for (int iy = -8; iy <= 8; ++iy) {
      if (std::abs(ix) > 7 || std::abs(iy) > 7) continue;  // slivers beyond the edge: no slope
      const CellEstimate e = both->Estimate({ix, iy});
      if (std::isnan(e.elevation)) continue;
      EXPECT_NEAR(e.elevation, Plane(ix, iy), 2e-6);
      ++compared;
    }
  }
  EXPECT_GT(compared, 150);
}

}  // namespace
}  // namespace bgkmap
