#include "bgkmap/proto/codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

namespace bgkmap {
namespace {

TEST(LayerCodecTest, EveryLayerRoundTrips) {
  std::set<int> values;
  for (int i = 0; i < kLayerCount; ++i) {
    const Layer layer = static_cast<Layer>(i);
    const v1::Layer proto = ToProto(layer);
    EXPECT_TRUE(v1::Layer_IsValid(proto)) << LayerName(layer);
    EXPECT_NE(proto, v1::LAYER_UNSPECIFIED) << LayerName(layer);
    EXPECT_TRUE(IsKnownLayer(proto)) << LayerName(layer);
    EXPECT_EQ(FromProto(proto), layer) << LayerName(layer);
    values.insert(proto);
  }
  EXPECT_EQ(values.size(), static_cast<size_t>(kLayerCount));
  // Every proto layer but LAYER_UNSPECIFIED is an engine layer.
  EXPECT_EQ(v1::Layer_descriptor()->value_count(), kLayerCount + 1);
  EXPECT_FALSE(IsKnownLayer(v1::LAYER_UNSPECIFIED));
}

TEST(LayerCodecTest, ListIsCheckedAndEmptyMeansEveryLayer) {
  google::protobuf::RepeatedField<int> list;
  std::vector<Layer> layers;
  ASSERT_TRUE(LayerListFromProto(list, "layers", &layers).ok());
  EXPECT_EQ(layers.size(), static_cast<size_t>(kLayerCount));
  list.Add(v1::LAYER_STATE);
  list.Add(v1::LAYER_ELEVATION);
  ASSERT_TRUE(LayerListFromProto(list, "layers", &layers).ok());
  EXPECT_EQ(layers, (std::vector<Layer>{Layer::kState, Layer::kElevation}));
  for (int bad : {0, kLayerCount + 1}) {
    list.Set(1, bad);
    const Status s = LayerListFromProto(list, "layers", &layers);
    EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
    EXPECT_EQ(s.message().rfind("layers[1]: " + std::to_string(bad), 0), 0u) << s.message();
  }
}

TEST(GridCodecTest, TileKeysAndCellBoxesRoundTrip) {
  v1::TileKey key;
  ToProto(TileKey{-3, 7}, &key);
  EXPECT_EQ(FromProto(key), (TileKey{-3, 7}));
  v1::CellBox box;
  const CellBox cells{{-5, 2}, {9, 11}};
  ToProto(cells, &box);
  const CellBox back = FromProto(box);
  EXPECT_EQ(back.min.x, -5);
  EXPECT_EQ(back.min.y, 2);
  EXPECT_EQ(back.max.x, 9);
  EXPECT_EQ(back.max.y, 11);
}

TEST(ScanCodecTest, PointCountsRoundTrip) {
  const ScanPointCounts counts{100, 90, 1, 2, 3, 4};
  v1::PointCounts message;
  ToProto(counts, &message);
  const ScanPointCounts back = FromProto(message);
  EXPECT_EQ(back.input, 100u);
  EXPECT_EQ(back.kept, 90u);
  EXPECT_EQ(back.dropped_nonfinite, 1u);
  EXPECT_EQ(back.dropped_range, 2u);
  EXPECT_EQ(back.dropped_height, 3u);
  EXPECT_EQ(back.dropped_out_of_bounds, 4u);
}

Raster SmallRaster() {
  Raster r;
  r.box = {{10, 20}, {13, 22}};
  r.stride = 1;
  r.cols = 4;
  r.rows = 3;
  r.resolution = 0.5;
  r.x0 = 5;
  r.y1 = 11.5;
  r.layers = {Layer::kElevation, Layer::kState};
  for (size_t l = 0; l < r.layers.size(); ++l) {
    r.data.emplace_back();
    for (int i = 0; i < 12; ++i) r.data.back().push_back(i == 5 ? NAN : 10.0f * l + i);
  }
  return r;
}

void ExpectSameValues(const Raster& a, const Raster& b) {
  ASSERT_EQ(a.layers, b.layers);
  for (size_t l = 0; l < a.layers.size(); ++l) {
    ASSERT_EQ(a.data[l].size(), b.data[l].size());
    for (size_t i = 0; i < a.data[l].size(); ++i) {
      if (std::isnan(a.data[l][i])) {
        EXPECT_TRUE(std::isnan(b.data[l][i]));
      } else {
        EXPECT_EQ(a.data[l][i], b.data[l][i]);
      }
    }
  }
}

TEST(RasterCodecTest, HeaderAndRowChunksRoundTrip) {
  const Raster r = SmallRaster();
  v1::RasterHeader header;
  ToProto(r, &header);
  Raster back = FromProto(header);
  EXPECT_EQ(back.box.min.x, 10);
  EXPECT_EQ(back.box.max.y, 22);
  EXPECT_EQ(back.cols, 4);
  EXPECT_EQ(back.rows, 3);
  EXPECT_EQ(back.resolution, 0.5);
  EXPECT_EQ(back.x0, 5);
  EXPECT_EQ(back.y1, 11.5);
  v1::RegionChunk first, second;
  AppendRows(r, 0, 2, first.mutable_layers());
  AppendRows(r, 2, 3, second.mutable_layers());
  EXPECT_FALSE(CopyRows(first.layers(), 2, 2, &back));  // past the last row
  ASSERT_TRUE(CopyRows(first.layers(), 0, 2, &back));
  EXPECT_FALSE(CopyRows(second.layers(), 2, 0, &back));  // wrong byte count
  ASSERT_TRUE(CopyRows(second.layers(), 2, 1, &back));
  ExpectSameValues(r, back);
}

TEST(RasterCodecTest, WatchedTileRasterHasTheTileGeometry) {
  const Raster r = SmallRaster();
  v1::TileUpdate update;
  ToProto(r.box, update.mutable_cells());
  update.set_resolution(r.resolution);
  AppendRows(r, 0, r.rows, update.mutable_layers());
  const Raster back = TileRasterFromProto(update);
  EXPECT_EQ(back.cols, 4);
  EXPECT_EQ(back.rows, 3);
  EXPECT_EQ(back.x0, 5);
  EXPECT_EQ(back.y1, 11.5);
  ExpectSameValues(r, back);
}

TEST(RasterCodecTest, PackedFloatsOfABadLengthAreRefused) {
  std::vector<float> out;
  EXPECT_FALSE(UnpackFloats(std::string(6, '\0'), &out));
  const float values[] = {1.5f, -2.0f};
  ASSERT_TRUE(UnpackFloats(PackFloats(values, 2), &out));
  EXPECT_EQ(out, (std::vector<float>{1.5f, -2.0f}));
}

}  // namespace
}  // namespace bgkmap
