// Region delta patches (issue 27): a tile's patch lands on the region raster's pixels, a part
// unknown everywhere becomes a tombstone, and a patch that does not fit the copy is refused
// with the copy unchanged.
#include "bgkmap/proto/region_delta_codec.h"

#include <gtest/gtest.h>

#include <cmath>

namespace bgkmap {
namespace {

Raster Filled(const CellBox& box, int stride, float value) {
  Raster r = RasterGeometry(0.1, box, {Layer::kElevation, Layer::kState}, stride);
  r.data.assign(2, std::vector<float>(static_cast<size_t>(r.rows * r.cols), value));
  return r;
}

TEST(RegionDeltaCodecTest, APatchLandsOnTheTilesPixelsAndUnknownIsATombstone) {
  const GridGeometry g(0.1, 64);
  const CellBox region{{-66, -66}, {65, 65}};  // stride 3: blocks straddle tile borders
  const CellBox cells = TilePatchCells(g, region, 3, {0, 0});
  EXPECT_EQ(cells.min, (CellIndex{0, 0}));    // 0 starts a block
  EXPECT_EQ(cells.max, (CellIndex{65, 65}));  // block 63..65 straddles tiles 0 and 1
  Raster copy = Filled(region, 3, 1.0f);
  v1::TilePatch patch;
  ToProto({0, 0}, region, Filled(cells, 3, 2.0f), &patch);
  EXPECT_FALSE(patch.tombstone());
  EXPECT_EQ(patch.row_start(), 0u);
  EXPECT_EQ(patch.col_start(), 22u);
  ASSERT_TRUE(ApplyPatch(patch, &copy));
  EXPECT_EQ(copy.data[0][22], 2.0f);
  EXPECT_EQ(copy.data[0][21], 1.0f);

  Raster unknown = Filled(cells, 3, 0.0f);
  std::fill(unknown.data[0].begin(), unknown.data[0].end(), UnknownValue(Layer::kElevation));
  ToProto({0, 0}, region, unknown, &patch);
  EXPECT_TRUE(patch.tombstone());
  EXPECT_EQ(patch.layers_size(), 0);
  ASSERT_TRUE(ApplyPatch(patch, &copy));
  EXPECT_TRUE(std::isnan(copy.data[0][22]));
  EXPECT_EQ(copy.data[1][22], 0.0f);
}

TEST(RegionDeltaCodecTest, APatchThatDoesNotFitIsRefusedAndChangesNothing) {
  const CellBox region{{0, 0}, {63, 63}};
  Raster copy = Filled(region, 1, 1.0f);
  const Raster before = copy;
  v1::TilePatch patch;
  ToProto({0, 0}, region, Filled({{0, 0}, {9, 9}}, 1, 2.0f), &patch);
  v1::TilePatch outside = patch;
  outside.set_row_start(60);
  EXPECT_FALSE(ApplyPatch(outside, &copy));
  v1::TilePatch short_layer = patch;
  short_layer.mutable_layers(1)->mutable_values()->resize(12);
  EXPECT_FALSE(ApplyPatch(short_layer, &copy));
  v1::TilePatch swapped = patch;
  swapped.mutable_layers()->SwapElements(0, 1);
  EXPECT_FALSE(ApplyPatch(swapped, &copy));
  v1::TilePatch tombstone_with_values = patch;
  tombstone_with_values.set_tombstone(true);
  EXPECT_FALSE(ApplyPatch(tombstone_with_values, &copy));
  EXPECT_EQ(copy.data, before.data);
}

}  // namespace
}  // namespace bgkmap
