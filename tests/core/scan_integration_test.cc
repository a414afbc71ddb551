#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bgkmap/core/sparse_kernel.h"
#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

std::unique_ptr<TerrainMap> NewMap(const MapParams& p = MapParams{}) {
  Result<std::unique_ptr<TerrainMap>> m = TerrainMap::Create(p);
  EXPECT_TRUE(m.ok()) << m.status().ToString();
  return std::move(m).value();
}

TEST(ScanIntegrationTest, OnePointSpreadsKernelWeightsByHand) {
  MapParams p;
  p.min_range = 0;
  auto map = NewMap(p);
  // Sensor at z = 1: a point 1.25 m below in cell (3, 4).
  Pose pose;
  pose.translation = {0, 0, 1};
  Result<ScanReport> r = map->IntegrateScan(std::vector<Point3f>{{0.35f, 0.45f, -1.25f}}, pose);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->observed_cells, 1u);
  for (int dy = -3; dy <= 3; ++dy) {
    for (int dx = -3; dx <= 3; ++dx) {
      const double d = 0.1 * std::hypot(dx, dy);
      const CellEstimate e = map->Estimate({3 + dx, 4 + dy});
      if (d < 0.3) {
        EXPECT_FLOAT_EQ(e.elevation_weight, static_cast<float>(SparseKernel(d, 0.3)));
        EXPECT_FLOAT_EQ(e.elevation, -0.25f);  // lambda = 0: any W > 0 gives y itself
        EXPECT_FLOAT_EQ(e.elevation_variance, static_cast<float>(0.01 / SparseKernel(d, 0.3)));
      } else {
        EXPECT_EQ(e.state, CellState::kUnknown) << dx << "," << dy;
      }
    }
  }
  EXPECT_EQ(map->CountKnownCells(), 25);
}

TEST(ScanIntegrationTest, TwoObservationsGiveTheKernelWeightedMean) {
  MapParams p;
  p.min_range = 0;
  auto map = NewMap(p);
  // Cells (0,0) with y = 1 and (2,0) with y = 2: cell (1,0) sits at 0.1 m from both.
  ASSERT_TRUE(map->IntegrateScan(std::vector<Point3f>{{0.05f, 0.05f, 1.0f}, {0.25f, 0.05f, 2.0f}},
                                 Pose{}, true)
                  .ok());
  const double k1 = SparseKernel(0.1, 0.3), k2 = SparseKernel(0.2, 0.3);
  EXPECT_NEAR(map->Estimate({1, 0}).elevation, 1.5, 1e-6);
  EXPECT_NEAR(map->Estimate({0, 0}).elevation, (1.0 + k2 * 2.0) / (1.0 + k2), 1e-6);
  EXPECT_NEAR(map->Estimate({1, 1}).elevation_weight, 2 * SparseKernel(0.1 * std::sqrt(2.0), 0.3),
              1e-6);
  (void)k1;
}

TEST(ScanIntegrationTest, FlatGroundBecomesTraversableAndAStepDoesNot) {
  auto map = NewMap();
  const Eigen::Vector3d origin(0, 0, 1.0);
  for (int s = 0; s < 5; ++s) {
    auto pts = testing::SampleSurface(testing::RollingWithStep, origin, 6.0, 40000, 17 + s);
    Result<ScanReport> r = map->IntegrateScan(pts, testing::At(origin));
    ASSERT_TRUE(r.ok());
    EXPECT_GT(r->feature_cells, 1000u);
  }
  // Flat-ish ground well away from the step at x = 2.
  EXPECT_EQ(map->EstimateAt(-2.0, 0.5).state, CellState::kTraversable);
  EXPECT_LT(map->EstimateAt(-2.0, 0.5).traversability, 0.3f);
  // On the 0.2 m step (> step_crit 0.15): non-traversable.
  EXPECT_EQ(map->EstimateAt(2.0, 0.5).state, CellState::kNonTraversable);
  EXPECT_GT(map->EstimateAt(2.0, 0.5).traversability, 0.6f);
  // The elevation reproduces the surface away from the step.
  EXPECT_NEAR(map->EstimateAt(-2.05, 0.55).elevation, testing::RollingWithStep(-2.05, 0.55), 0.01);
}

// Pose noise (semantics "Pose noise"): sparse scans of flat ground whose poses differ by 6 cm
// in z leave neighbourhoods of cells last set by different scans, steps of noise; pose_sigma_z
// discounts them, and a 0.3 m step stays an obstacle.
TEST(ScanIntegrationTest, PoseSigmaZDiscountsTheStepsPoseNoiseMakes) {
  auto traversability_at = [](double sigma_z, double x) {
    MapParams p;
    p.pose_sigma_z = sigma_z;
    auto map = NewMap(p);
    const auto ground = [](double gx, double) { return gx > 2.0 ? 0.3 : 0.0; };
    for (int s = 0; s < 8; ++s) {
      const Eigen::Vector3d truth(0, 0, 1.0);
      const Eigen::Vector3d believed(0, 0, 1.0 + (s % 2 == 0 ? 0.03 : -0.03));
      // The points are where the sensor truly was; the pose the map gets is off by +-3 cm.
      auto pts = testing::SampleSurface(ground, truth, 6.0, 3000, 31 + s);
      EXPECT_TRUE(map->IntegrateScan(pts, testing::At(believed)).ok());
    }
    return map->EstimateAt(x, 0.55).traversability;
  };
  const float flat_noisy = traversability_at(0.0, -2.0);
  const float flat_discounted = traversability_at(0.03, -2.0);
  EXPECT_LT(flat_discounted, 0.5f * flat_noisy) << flat_noisy << " -> " << flat_discounted;
  EXPECT_GT(traversability_at(0.03, 2.0), 0.6f);  // the 0.3 m step
}

TEST(ScanIntegrationTest, ReportsExactlyTheTilesWhoseStatisticsChanged) {
  MapParams p;
  p.tile_size = 8;
  auto map = NewMap(p);
  const Eigen::Vector3d origin(0.3, -0.2, 1.0);
  auto pts = testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 3000, 5);
  Result<ScanReport> r = map->IntegrateScan(pts, testing::At(origin));
  ASSERT_TRUE(r.ok());
  std::vector<TileKey> nonempty;
  map->ForEachTile([&](TileKey k, const Tile& t) {
    if (!t.Empty()) nonempty.push_back(k);
    EXPECT_EQ(t.version(), 1u);
  });
  std::sort(nonempty.begin(), nonempty.end());
  EXPECT_EQ(r->changed_tiles, nonempty);
  EXPECT_EQ(map->tile_count(), nonempty.size()) << "no empty tiles are created";
}

TEST(ScanIntegrationTest, ElevationStatisticsDoNotDependOnScanOrder) {
  std::vector<std::pair<std::vector<Point3f>, Pose>> scans;
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector3d origin(0.7 * s, -0.4 * s, 1.0);
    scans.emplace_back(testing::SampleSurface(testing::RollingWithStep, origin, 3.0, 4000, 50 + s),
                       testing::At(origin));
  }
  // The paper's accumulation: with dynamics, caps and free-space evidence depend on the order.
  MapParams p;
  p.dynamics = Dynamics::kOff;
  auto forward = NewMap(p);
  auto backward = NewMap(p);
  for (size_t i = 0; i < scans.size(); ++i) {
    ASSERT_TRUE(forward->IntegrateScan(scans[i].first, scans[i].second).ok());
    const auto& [pts, pose] = scans[scans.size() - 1 - i];
    ASSERT_TRUE(backward->IntegrateScan(pts, pose).ok());
  }
  const CellBox box = forward->KnownBounds();
  ASSERT_EQ(box, backward->KnownBounds());
  for (int y = box.min.y; y <= box.max.y; ++y) {
    for (int x = box.min.x; x <= box.max.x; ++x) {
      const Tile* a = forward->FindTile(forward->geometry().TileOf({x, y}));
      const Tile* b = backward->FindTile(backward->geometry().TileOf({x, y}));
      const int i = forward->geometry().LocalIndex({x, y});
      ASSERT_EQ(a == nullptr, b == nullptr);
      if (a == nullptr) continue;
      // Sums in another order: equal up to rounding.
      ASSERT_NEAR(a->w()[i], b->w()[i], 1e-12 * (1 + a->w()[i]));
      ASSERT_NEAR(a->s()[i], b->s()[i], 1e-12 * (1 + std::abs(a->s()[i])));
    }
  }
}

TEST(ScanIntegrationTest, ClearBoxStampsTheVersionItIsGiven) {
  auto map = NewMap();
  const Eigen::Vector3d origin(0, 0, 1.0);
  ASSERT_TRUE(
      map->IntegrateScan(testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 5000, 3),
                         testing::At(origin))
          .ok());
  const CellBox left{map->KnownBounds().min, {0, 0}};
  const std::vector<TileKey> changed = map->ClearBox(left, 42);
  ASSERT_FALSE(changed.empty());
  for (TileKey k : changed) {
    if (const Tile* t = map->FindTile(k)) {  // tiles left empty are dropped
      EXPECT_EQ(t->version(), 42u);
    }
  }
  EXPECT_EQ(map->version(), 1u) << "an explicit version leaves the map's counter to the caller";
}

TEST(ScanIntegrationTest, RejectedScanLeavesTheMapUnchanged) {
  auto map = NewMap();
  const Eigen::Vector3d origin(0, 0, 1.0);
  auto pts = testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 2000, 9);
  ASSERT_TRUE(map->IntegrateScan(pts, testing::At(origin)).ok());
  const int64_t known = map->CountKnownCells();
  const uint64_t version = map->version();
  Pose bad = testing::At(origin);
  bad.rotation(0, 1) = 0.3;
  Result<ScanReport> r = map->IntegrateScan(pts, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(map->CountKnownCells(), known);
  EXPECT_EQ(map->version(), version);
}

TEST(ScanIntegrationTest, NaNPointsAreDroppedAndCountedNotIntegrated) {
  auto map = NewMap();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Result<ScanReport> r = map->IntegrateScan(
      std::vector<Point3f>{{nan, 1, -1}, {2, nan, -1}, {2, 2, nan}}, testing::At({0, 0, 1}));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->counts.dropped_nonfinite, 3u);
  EXPECT_EQ(map->CountKnownCells(), 0);
  EXPECT_EQ(map->tile_count(), 0u);
}

TEST(ScanIntegrationTest, ClearBoxForgetsCellsAndDropsEmptyTiles) {
  auto map = NewMap();
  const Eigen::Vector3d origin(0, 0, 1.0);
  ASSERT_TRUE(
      map->IntegrateScan(testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 5000, 3),
                         testing::At(origin))
          .ok());
  const CellBox all = map->KnownBounds();
  const CellBox left{all.min, {0, all.max.y}};
  map->ClearBox(left);
  EXPECT_EQ(map->Estimate({-10, 0}).state, CellState::kUnknown);
  EXPECT_FALSE(
      std::isnan(map->Estimate({10, 0}).elevation_weight));  // kept (maybe seen too little)
  map->ClearBox(all);
  EXPECT_EQ(map->CountKnownCells(), 0);
  EXPECT_EQ(map->version(), 3u);  // the scan, then two clears
  EXPECT_EQ(map->tile_count(), 0u);
}

TEST(ScanIntegrationTest, ClearBoxCanKeepTheTilesItEmpties) {
  auto map = NewMap();
  const Eigen::Vector3d origin(0, 0, 1.0);
  ASSERT_TRUE(
      map->IntegrateScan(testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 5000, 3),
                         testing::At(origin))
          .ok());
  const size_t tiles = map->tile_count();
  ASSERT_GT(tiles, 0u);  // or the loop below checks nothing
  const std::vector<TileKey> changed = map->ClearBox(map->KnownBounds(), 7, /*keep_empty=*/true);
  EXPECT_EQ(changed.size(), tiles);
  EXPECT_EQ(map->tile_count(), tiles);
  EXPECT_EQ(map->CountKnownCells(), 0);
  for (TileKey k : changed) {
    ASSERT_NE(map->FindTile(k), nullptr);
    EXPECT_TRUE(map->FindTile(k)->Empty());
    EXPECT_EQ(map->FindTile(k)->version(), 7u);
  }
}

}  // namespace
}  // namespace bgkmap
