#include "bgkmap/core/raster.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "stride_oracle.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

std::unique_ptr<TerrainMap> TwoCellMap() {
  MapParams p;
  p.method = Method::kBaseline;  // no spreading: exactly the observed cells are known
  auto map = std::move(TerrainMap::Create(p)).value();
  EXPECT_TRUE(map->IntegrateScan(std::vector<Point3f>{{0.05f, 0.05f, 1.0f}, {0.15f, 0.35f, 3.0f}},
                                 Pose{}, true)
                  .ok());
  return map;
}

TEST(RasterTest, RowsRunNorthToSouthAndUnknownIsNaN) {
  auto map = TwoCellMap();
  const CellBox box{{0, 0}, {1, 3}};  // 2 columns, 4 rows
  const Raster r = ExtractRaster(*map, box, {Layer::kElevation, Layer::kState});
  ASSERT_EQ(r.cols, 2);
  ASSERT_EQ(r.rows, 4);
  EXPECT_DOUBLE_EQ(r.x0, 0.0);
  EXPECT_DOUBLE_EQ(r.y1, 0.4);
  const std::vector<float>& elev = *r.Find(Layer::kElevation);
  EXPECT_FLOAT_EQ(elev[0 * 2 + 1], 3.0f);  // cell (1, 3): top row
  EXPECT_FLOAT_EQ(elev[3 * 2 + 0], 1.0f);  // cell (0, 0): bottom row
  EXPECT_TRUE(std::isnan(elev[1 * 2 + 0]));
  const std::vector<float>& state = *r.Find(Layer::kState);
  EXPECT_EQ(state[1 * 2 + 0], 0.0f);  // unknown
  EXPECT_EQ(r.Find(Layer::kTraversability), nullptr);
}

TEST(RasterTest, StrideMergesStatisticsAndKeepsTheWorstTraversability) {
  MapParams p;
  auto map = std::move(TerrainMap::Create(p)).value();
  Tile& t = map->GetOrCreateTile({0, 0});
  // Cell (0,0): W=1,S=1, flat; cell (1,0): W=3,S=9, rough.
  t.w()[0] = 1;
  t.s()[0] = 1;
  t.a()[0] = 0.0f;
  t.b()[0] = 10.0f;
  t.w()[1] = 3;
  t.s()[1] = 9;
  t.a()[1] = 9.0f;
  t.b()[1] = 1.0f;
  const Raster r = ExtractRaster(*map, {{0, 0}, {3, 3}},
                                 {Layer::kElevation, Layer::kTraversability, Layer::kState}, 2);
  ASSERT_EQ(r.cols, 2);
  ASSERT_EQ(r.rows, 2);
  EXPECT_DOUBLE_EQ(r.resolution, 0.2);
  // Bottom-left pixel (row 1, col 0) holds cells (0..1, 0..1).
  EXPECT_FLOAT_EQ((*r.Find(Layer::kElevation))[2], 10.0f / 4.0f);
  EXPECT_FLOAT_EQ((*r.Find(Layer::kTraversability))[2], map->Estimate({1, 0}).traversability);
  EXPECT_EQ((*r.Find(Layer::kState))[2], 2.0f);
  EXPECT_TRUE(std::isnan((*r.Find(Layer::kElevation))[0]));
}

void SetCell(Tile& t, int x, int y, double w, double s, float a, float b) {
  const int i = y * t.tile_size() + x;
  t.w()[i] = w;
  t.s()[i] = s;
  t.a()[i] = a;
  t.b()[i] = b;
}

// The worst traversability and the worst variance are kept separately, each the maximum over the
// block, even when they come from different cells, and a block whose means are all below the
// threshold is non-traversable if one cell's variance is not.
// Mutations checked (core/src/raster.cc, PixelAggregate::Add / Estimate): keeping the last cell's
// variance (`worst_var = e.traversability_variance`) fails the first block; dropping
// `e.traversability_variance < p.variance_threshold` from the state fails the third.
TEST(RasterTest, StrideKeepsTheWorstVarianceOfAnyCellAndItDecidesTheState) {
  MapParams p;
  auto map = std::move(TerrainMap::Create(p)).value();
  Tile& t = map->GetOrCreateTile({0, 0});
  // B before A in ExtractRaster's scan order (rows upward), so "the last cell's" variance is A's.
  SetCell(t, 1, 1, 1, 1, 9.0f, 1.0f);  // A: mean 0.9, variance 0.008
  SetCell(t, 0, 0, 1, 1, 0.3f, 0.7f);  // B: mean 0.3, variance 0.105
  SetCell(t, 2, 0, 1, 1, 1.0f, 9.0f);  // C: mean 0.1, variance 0.008
  SetCell(t, 3, 1, 1, 1, 2.0f, 8.0f);  // D: mean 0.2, variance 0.015
  SetCell(t, 4, 0, 1, 1, 1.0f, 9.0f);  // E: mean 0.1, variance 0.008
  SetCell(t, 5, 1, 1, 1, 0.3f, 0.7f);  // F: mean 0.3, variance 0.105
  const CellEstimate a = map->Estimate({1, 1}), b = map->Estimate({0, 0}),
                     c = map->Estimate({2, 0}), d = map->Estimate({3, 1}),
                     f = map->Estimate({5, 1});
  // The premises: A is the worse mean and B the worse variance; only B and F break the variance
  // threshold, and C..F all have means below the traversability threshold.
  ASSERT_GT(a.traversability, b.traversability);
  ASSERT_GT(b.traversability_variance, a.traversability_variance);
  ASSERT_GE(b.traversability_variance, p.variance_threshold);
  ASSERT_LT(d.traversability_variance, p.variance_threshold);
  ASSERT_LT(f.traversability, p.trav_threshold);
  ASSERT_LT(d.traversability, p.trav_threshold);

  const std::vector<Layer> layers = {Layer::kTraversability, Layer::kTraversabilityVariance,
                                     Layer::kState};
  const Raster r = ExtractRaster(*map, {{0, 0}, {5, 1}}, layers, 2);
  ASSERT_EQ(r.cols, 3);
  ASSERT_EQ(r.rows, 1);
  const std::vector<float>&trav = r.data[0], &var = r.data[1], &state = r.data[2];
  EXPECT_EQ(trav[0], a.traversability);
  EXPECT_EQ(var[0], b.traversability_variance);  // not A's: the worst variance of any cell
  EXPECT_EQ(state[0], 2.0f);
  EXPECT_EQ(trav[1], d.traversability);
  EXPECT_EQ(var[1], d.traversability_variance);
  EXPECT_EQ(state[1], 1.0f);  // every mean and variance under its threshold
  EXPECT_EQ(trav[2], f.traversability);
  EXPECT_EQ(var[2], f.traversability_variance);
  EXPECT_EQ(state[2], 0.0f);  // means fine, F's variance is not: seen too little (dynamics)
  EXPECT_LT(c.traversability, d.traversability);
}

// ExtractRaster at several strides and unaligned boxes equals the brute-force oracle
// (stride_oracle.h, from the rule in docs/semantics.md and per-cell TerrainMap::Estimate) on a
// map with real scans: an obstacle step, unknown holes, blocks split over tile borders.
// Elevation and its variance sum W and S in another order than ExtractRaster, so they are
// compared to a float's rounding; traversability, its variance, the state, W, the disagreement
// and the block reason exactly.
// Mutations checked (core/src/raster.cc): `std::min` for `std::max` in worst_trav; the last
// cell's variance instead of the maximum; dropping the variance threshold from the state; not
// summing `s` (elevation of one cell) -- each fails here.
// Stride 1 is each cell's own estimate, layer by layer and bit for bit, however the layers are
// listed (a layer asked for twice too), with and without plane moments (bgk-ll).
TEST(RasterTest, EachPixelIsItsCellsEstimateInEveryLayer) {
  for (Method method : {Method::kBgkPlus, Method::kBgkLocalLinear, Method::kBaseline}) {
    MapParams p;
    p.method = method;
    p.tile_size = 16;
    auto map = std::move(TerrainMap::Create(p)).value();
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d origin(1.5 * k, 0.2 * k, 1.0);
      ASSERT_TRUE(map->IntegrateScan(testing::SampleSurface(testing::RollingWithStep, origin, 3.0,
                                                            2000, 3u + k),
                                     testing::At(origin))
                      .ok());
    }
    const CellBox known = map->KnownBounds();
    const CellBox box{{known.min.x - 2, known.min.y - 1}, {known.max.x + 1, known.max.y + 3}};
    const std::vector<Layer> layers = {Layer::kBlockReason,       Layer::kState,
                                       Layer::kElevation,         Layer::kTraversability,
                                       Layer::kDisagreement,      Layer::kElevationWeight,
                                       Layer::kElevationVariance, Layer::kTraversabilityVariance,
                                       Layer::kElevation};
    const Raster r = ExtractRaster(*map, box, layers);
    ASSERT_EQ(r.data.size(), layers.size());
    int known_pixels = 0, mismatches = 0;
    for (int y = box.min.y; y <= box.max.y; ++y) {
      for (int x = box.min.x; x <= box.max.x; ++x) {
        const CellEstimate e = map->Estimate({x, y});
        const size_t pixel = static_cast<size_t>(box.max.y - y) * r.cols + (x - box.min.x);
        known_pixels += !std::isnan(e.elevation_weight);
        for (size_t l = 0; l < layers.size(); ++l) {
          const float want =
              std::isnan(e.elevation_weight) ? UnknownValue(layers[l]) : e.Get(layers[l]);
          const float got = r.data[l][pixel];
          if (std::memcmp(&got, &want, sizeof got) != 0 && mismatches++ < 5) {
            ADD_FAILURE() << MethodName(method) << " cell (" << x << ", " << y << ") layer "
                          << LayerName(layers[l]) << ": raster " << got << ", estimate " << want;
          }
        }
      }
    }
    EXPECT_EQ(mismatches, 0) << MethodName(method);
    EXPECT_GT(known_pixels, 500) << MethodName(method);
  }
}

TEST(RasterTest, StrideEqualsBruteForceOracle) {
  MapParams p;
  p.tile_size = 16;  // blocks straddle tile borders
  auto map = std::move(TerrainMap::Create(p)).value();
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d origin(1.0 * k, 0.3 * k, 1.0);
    ASSERT_TRUE(map->IntegrateScan(
                       testing::SampleSurface(testing::RollingWithStep, origin, 4.0, 3000, 7u + k),
                       testing::At(origin))
                    .ok());
  }
  const CellBox known = map->KnownBounds();
  ASSERT_GT(known.width(), 40);
  const std::vector<Layer> all = {Layer::kElevation,      Layer::kElevationVariance,
                                  Layer::kTraversability, Layer::kTraversabilityVariance,
                                  Layer::kState,          Layer::kElevationWeight,
                                  Layer::kDisagreement,   Layer::kBlockReason};
  int states[3] = {0, 0, 0};
  for (int stride : {2, 3, 5, 8}) {
    // Unaligned: start 3 cells outside the known area (unknown blocks too), odd size.
    const CellBox box{{known.min.x - 3, known.min.y - 3}, {known.max.x + 2, known.max.y + 4}};
    const Raster got = ExtractRaster(*map, box, all, stride);
    const Raster want = testing::StrideOracle(*map, box, all, stride);
    ASSERT_EQ(got.cols, want.cols);
    ASSERT_EQ(got.rows, want.rows);
    ASSERT_EQ(got.layers, want.layers);
    int bad = 0;
    for (size_t l = 0; l < all.size(); ++l) {
      const bool rounded = all[l] == Layer::kElevation || all[l] == Layer::kElevationVariance;
      for (size_t i = 0; i < want.data[l].size(); ++i) {
        const float g = got.data[l][i], w = want.data[l][i];
        const bool same = (std::isnan(g) && std::isnan(w)) ||
                          (rounded ? std::abs(g - w) <= 1e-5f * std::max(1.0f, std::abs(w))
                                   : std::memcmp(&g, &w, sizeof g) == 0);
        if (!same && bad++ < 5) {
          ADD_FAILURE() << "stride " << stride << " layer " << LayerName(all[l]) << " pixel " << i
                        << ": ExtractRaster " << g << ", oracle " << w;
        }
        if (all[l] == Layer::kState) ++states[static_cast<int>(w)];
      }
    }
    EXPECT_EQ(bad, 0) << "stride " << stride;
  }
  // The map exercises every state, or the comparison proves little.
  EXPECT_GT(states[0], 0);
  EXPECT_GT(states[1], 0);
  EXPECT_GT(states[2], 0);
}

}  // namespace
}  // namespace bgkmap
