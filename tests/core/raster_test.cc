#include "bgkmap/core/raster.h"

#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace bgkmap
