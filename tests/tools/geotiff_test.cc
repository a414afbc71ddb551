#include "bgkmap/io/geotiff.h"

#include <fmt/format.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <thread>

#include "raster_fixture.h"
#include "test_files.h"

namespace bgkmap::io {
namespace {

using testing::MakeTestRaster;
using testing::SameData;
using testing::TempDir;

// Bitwise equality, so NaN == NaN and -0 != 0.
bool SameBits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

TEST(GeoTiffTest, RoundTripKeepsValuesGeometryAndNaNs) {
  TempDir dir;
  const Raster in = MakeTestRaster(37, 23);
  const std::string path = dir.Path("map.tif");
  Status s = WriteGeoTiff(in, path);
  ASSERT_TRUE(s.ok()) << s.message();

  Result<Raster> out = ReadGeoTiff(path);
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out->cols, in.cols);
  EXPECT_EQ(out->rows, in.rows);
  EXPECT_EQ(out->resolution, in.resolution);
  EXPECT_EQ(out->x0, in.x0);
  EXPECT_EQ(out->y1, in.y1);
  EXPECT_EQ(out->stride, in.stride);
  EXPECT_EQ(out->box, in.box);
  ASSERT_EQ(out->layers, in.layers);
  int nans = 0;
  for (size_t l = 0; l < in.layers.size(); ++l) {
    ASSERT_EQ(out->data[l].size(), in.data[l].size());
    for (size_t i = 0; i < in.data[l].size(); ++i) {
      ASSERT_TRUE(SameBits(out->data[l][i], in.data[l][i]))
          << LayerName(in.layers[l]) << "[" << i << "]: " << out->data[l][i] << " vs "
          << in.data[l][i];
      nans += std::isnan(in.data[l][i]);
    }
  }
  EXPECT_GT(nans, 100);
}

// What other GIS tools see: band names, NaN NoData, north-up transform, compression.
TEST(GeoTiffTest, FileFollowsTheGeoTiffContract) {
  TempDir dir;
  const Raster in = MakeTestRaster(300, 200);
  const std::string path = dir.Path("map.tif");
  ASSERT_TRUE(WriteGeoTiff(in, path, {.spatial_reference = "EPSG:32633"}).ok());

  GDALDataset* ds = GDALDataset::FromHandle(GDALOpen(path.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  EXPECT_EQ(gt[0], in.x0);
  EXPECT_EQ(gt[1], in.resolution);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[3], in.y1);
  EXPECT_EQ(gt[4], 0.0);
  EXPECT_EQ(gt[5], -in.resolution);
  ASSERT_EQ(ds->GetRasterCount(), 4);
  const char* names[] = {"elevation", "elevation_variance", "traversability", "state"};
  for (int b = 1; b <= 4; ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b);
    EXPECT_STREQ(band->GetDescription(), names[b - 1]);
    EXPECT_EQ(band->GetRasterDataType(), GDT_Float32);
    int has_nodata = 0;
    EXPECT_TRUE(std::isnan(band->GetNoDataValue(&has_nodata)));
    EXPECT_TRUE(has_nodata);
  }
  const char* compression = ds->GetMetadataItem("COMPRESSION", "IMAGE_STRUCTURE");
  ASSERT_NE(compression, nullptr);
  EXPECT_STREQ(compression, "DEFLATE");
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  ASSERT_NE(srs, nullptr);
  EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "32633");
  GDALClose(GDALDataset::ToHandle(ds));
}

// A COG: GDAL reports LAYOUT=COG, it has overviews, carries the CRS, and reads back bitwise.
TEST(GeoTiffTest, CloudOptimizedWithOverviewsAndCrs) {
  TempDir dir;
  Raster in = MakeTestRaster(1200, 900);
  const std::string path = dir.Path("cog.tif");
  GeoTiffOptions options;
  options.cloud_optimized = true;
  options.spatial_reference = "EPSG:32610";
  ASSERT_TRUE(WriteGeoTiff(in, path, options).ok());
  GDALDataset* ds = GDALDataset::FromHandle(GDALOpen(path.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  const char* layout = ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE");
  EXPECT_STREQ(layout, "COG");
  EXPECT_GT(ds->GetRasterBand(1)->GetOverviewCount(), 0);
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  ASSERT_NE(srs, nullptr);
  EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "32610");
  GDALClose(ds);
  Result<Raster> out = ReadGeoTiff(path);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->box, in.box);
  EXPECT_EQ(out->layers, in.layers);
  EXPECT_TRUE(SameData(*out, in));
  // A plain GeoTIFF is not a COG.
  ASSERT_TRUE(WriteGeoTiff(in, dir.Path("plain.tif")).ok());
  ds = GDALDataset::FromHandle(GDALOpen(dir.Path("plain.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE"), nullptr);
  GDALClose(ds);
  options.spatial_reference = "EPSG:not-a-code";
  EXPECT_EQ(WriteGeoTiff(in, dir.Path("bad.tif"), options).code(), Status::Code::kInvalidArgument);
}

// Compressing on several threads changes nothing in the file (`bgkmap build --threads`): plain
// and COG, with enough tiles per band (256 x 256; a COG's 512 x 512) for both threads to take some.
TEST(GeoTiffTest, ThreadsWriteTheSameBytes) {
  TempDir dir;
  const Raster in = MakeTestRaster(800, 600);
  for (const bool cog : {false, true}) {
    std::string files[2];
    for (const int threads : {1, 2}) {
      GeoTiffOptions options;
      options.cloud_optimized = cog;
      options.threads = threads;
      const std::string path = dir.Path(fmt::format("t{}_{}.tif", threads, cog));
      ASSERT_TRUE(WriteGeoTiff(in, path, options).ok());
      files[threads - 1] = testing::ReadBytes(path);
    }
    ASSERT_FALSE(files[0].empty());
    EXPECT_TRUE(files[0] == files[1]) << (cog ? "COG" : "plain GeoTIFF");
  }
}

TEST(GeoTiffTest, ConcurrentWritesAndReads) {
  TempDir dir;
  const Raster in = MakeTestRaster(64, 48);
  std::vector<std::thread> threads;
  std::vector<int> ok(4, 0);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      const std::string path = dir.Path(fmt::format("t{}.tif", t));
      Result<Raster> out = WriteGeoTiff(in, path).ok() ? ReadGeoTiff(path) : Status::IoError("");
      ok[t] = out.ok() && SameData(*out, in);
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(ok, std::vector<int>(4, 1));
}

TEST(GeoTiffTest, InvalidRastersAreRejected) {
  TempDir dir;
  const std::string path = dir.Path("bad.tif");
  Raster empty;
  EXPECT_EQ(WriteGeoTiff(empty, path).code(), Status::Code::kInvalidArgument);
  Raster short_layer = MakeTestRaster(5, 4);
  short_layer.data[1].pop_back();
  Status s = WriteGeoTiff(short_layer, path);
  EXPECT_EQ(s.code(), Status::Code::kInvalidArgument);
  EXPECT_NE(s.message().find("elevation_variance has 19 values, expected 4 x 5"), std::string::npos)
      << s.message();
  Raster no_data = MakeTestRaster(5, 4);
  no_data.data.pop_back();
  EXPECT_EQ(WriteGeoTiff(no_data, path).code(), Status::Code::kInvalidArgument);
  Raster bad_res = MakeTestRaster(5, 4);
  bad_res.resolution = 0;
  EXPECT_EQ(WriteGeoTiff(bad_res, path).code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(WriteGeoTiff(MakeTestRaster(5, 4), path, {.spatial_reference = "EPSG:nonsense"}).code(),
            Status::Code::kInvalidArgument);
}

TEST(GeoTiffTest, GdalErrorsBecomeOneLineStatuses) {
  TempDir dir;
  const std::string unwritable = dir.Path("no/such/dir/map.tif");
  Status s = WriteGeoTiff(MakeTestRaster(5, 4), unwritable);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message().rfind(unwritable + ": cannot create GeoTIFF: ", 0), 0u) << s.message();

  const std::string not_tiff = dir.Path("not.tif");
  testing::WriteBytes(not_tiff, "this is not a tiff");
  Result<Raster> r = ReadGeoTiff(not_tiff);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind(not_tiff + ": cannot open as GeoTIFF", 0), 0u)
      << r.status().message();
  EXPECT_EQ(r.status().message().find('\n'), std::string::npos);
  EXPECT_FALSE(ReadGeoTiff(dir.Path("missing.tif")).ok());
}

TEST(GeoTiffTest, ForeignBandNamesAreRejected) {
  TempDir dir;
  const std::string path = dir.Path("foreign.tif");
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDataset* ds = driver->Create(path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
  ASSERT_NE(ds, nullptr);
  double gt[6] = {10, 2, 0, 20, 0, -2};
  ds->SetGeoTransform(gt);
  ds->GetRasterBand(1)->SetDescription("height");
  GDALClose(GDALDataset::ToHandle(ds));
  Result<Raster> r = ReadGeoTiff(path);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("band 1 description 'height' is not a layer name"),
            std::string::npos)
      << r.status().message();
}

// A north-up GeoTIFF without BGKMAP metadata and with a finite NoData still reads as a Raster.
TEST(GeoTiffTest, ForeignFileWithoutMetadataGetsBoxFromGeotransform) {
  TempDir dir;
  const std::string path = dir.Path("foreign.tif");
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDataset* ds = driver->Create(path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
  ASSERT_NE(ds, nullptr);
  double gt[6] = {10, 2, 0, 20, 0, -2};
  ds->SetGeoTransform(gt);
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetDescription("elevation");
  band->SetNoDataValue(-9999);
  std::vector<float> v = {1, 2, 3, 4, 5, -9999, 7, 8, 9, 10, 11, 12};
  ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, 4, 3, v.data(), 4, 3, GDT_Float32, 0, 0), CE_None);
  GDALClose(GDALDataset::ToHandle(ds));

  Result<Raster> r = ReadGeoTiff(path);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->stride, 1);
  EXPECT_EQ(r->box, (CellBox{{5, 7}, {8, 9}}));  // x 10..18 m, y 14..20 m at 2 m
  EXPECT_TRUE(std::isnan(r->data[0][5]));
  EXPECT_EQ(r->data[0][6], 7.0f);
}

}  // namespace
}  // namespace bgkmap::io
