// GeoTiffWriter: a raster written part by part (what `bgkmap query` streams, window by window) is
// the raster written whole, pixel for pixel, for a plain GeoTIFF and a COG; parts that do not
// fit are refused; what is never written reads as unknown; an unfinished file is not left behind.
#include "bgkmap/io/geotiff_writer.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "bgkmap/io/geotiff.h"
#include "raster_fixture.h"
#include "test_files.h"

namespace bgkmap::io {
namespace {

using testing::MakeTestRaster;
using testing::SameData;
using testing::TempDir;

// The pixels [col0, col0 + cols) x [row0, row0 + rows) of `r` as a raster of their own.
Raster Part(const Raster& r, int64_t col0, int64_t row0, int64_t cols, int64_t rows) {
  Raster p = r;
  const int s = r.stride;
  p.cols = cols;
  p.rows = rows;
  p.box.min.x = r.box.min.x + static_cast<int>(col0) * s;
  p.box.max.x = p.box.min.x + static_cast<int>(cols) * s - 1;
  p.box.max.y = r.box.max.y - static_cast<int>(row0) * s;
  p.box.min.y = p.box.max.y - static_cast<int>(rows) * s + 1;
  p.x0 = r.x0 + static_cast<double>(col0) * r.resolution;
  p.y1 = r.y1 - static_cast<double>(row0) * r.resolution;
  for (size_t l = 0; l < r.layers.size(); ++l) {
    p.data[l].clear();
    for (int64_t row = row0; row < row0 + rows; ++row) {
      const auto begin = r.data[l].begin() + row * r.cols + col0;
      p.data[l].insert(p.data[l].end(), begin, begin + cols);
    }
  }
  return p;
}

// `in` written in windows of `edge` pixels, north first, each row west to east.
Status WriteInWindows(const Raster& in, const std::string& path, const GeoTiffOptions& options,
                      int64_t edge) {
  Raster geometry = in;
  geometry.data.clear();
  Result<std::unique_ptr<GeoTiffWriter>> w = GeoTiffWriter::Create(geometry, path, options);
  if (!w.ok()) return w.status();
  for (int64_t row = 0; row < in.rows; row += edge) {
    for (int64_t col = 0; col < in.cols; col += edge) {
      const Raster p =
          Part(in, col, row, std::min(edge, in.cols - col), std::min(edge, in.rows - row));
      if (Status s = (*w)->Write(p); !s.ok()) return s;
    }
  }
  return (*w)->Finish();
}

TEST(GeoTiffWriterTest, WindowsMakeTheRasterWrittenWholePixelForPixel) {
  TempDir dir;
  const Raster in = MakeTestRaster(700, 530);  // 3 x 3 windows of 256, the last ones partial
  for (bool cog : {false, true}) {
    GeoTiffOptions options;
    options.cloud_optimized = cog;
    options.spatial_reference = "EPSG:32610";
    options.origin = {551000, 4180000, 12.5};
    const std::string whole = dir.Path(cog ? "whole_cog.tif" : "whole.tif");
    const std::string parts = dir.Path(cog ? "parts_cog.tif" : "parts.tif");
    ASSERT_TRUE(WriteGeoTiff(in, whole, options).ok());
    Status s = WriteInWindows(in, parts, options, kGeoTiffBlockPixels);
    ASSERT_TRUE(s.ok()) << s.ToString();
    Result<Raster> a = ReadGeoTiff(whole), b = ReadGeoTiff(parts);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(b->box, in.box);
    EXPECT_EQ(b->x0, a->x0);
    EXPECT_EQ(b->y1, a->y1);
    EXPECT_EQ(b->layers, a->layers);
    EXPECT_TRUE(SameData(*a, *b)) << (cog ? "COG" : "GTiff");
    // The height shift reached every part: elevation + 12.5 where known.
    const size_t known = 300 * 700 + 650;
    EXPECT_FLOAT_EQ(b->data[0][known], in.data[0][known] + 12.5f);
    // Each block stored once: the files are as large as the whole one.
    EXPECT_EQ(std::filesystem::file_size(parts), std::filesystem::file_size(whole));
    EXPECT_FALSE(std::filesystem::exists(parts + ".staging.tif"));
    if (cog) {
      GDALDataset* ds = GDALDataset::FromHandle(GDALOpen(parts.c_str(), GA_ReadOnly));
      ASSERT_NE(ds, nullptr);
      EXPECT_STREQ(ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE"), "COG");
      EXPECT_GT(ds->GetRasterBand(1)->GetOverviewCount(), 0);
      GDALClose(ds);
    }
  }
}

TEST(GeoTiffWriterTest, PartsThatDoNotFitAreRefused) {
  TempDir dir;
  const Raster in = MakeTestRaster(300, 200);
  Raster geometry = in;
  geometry.data.clear();
  Result<std::unique_ptr<GeoTiffWriter>> w = GeoTiffWriter::Create(geometry, dir.Path("a.tif"), {});
  ASSERT_TRUE(w.ok());
  Raster shifted = Part(in, 0, 0, 10, 10);
  shifted.box.min.x += 1;  // off the stride grid
  EXPECT_EQ((*w)->Write(shifted).code(), Status::Code::kInvalidArgument);
  EXPECT_EQ((*w)->Write(Part(in, 295, 0, 10, 10)).code(), Status::Code::kInvalidArgument)
      << "past the east edge";
  Raster other = Part(in, 0, 0, 10, 10);
  other.stride = 1;
  EXPECT_EQ((*w)->Write(other).code(), Status::Code::kInvalidArgument);
  Raster short_data = Part(in, 0, 0, 10, 10);
  short_data.data[1].pop_back();
  EXPECT_EQ((*w)->Write(short_data).code(), Status::Code::kInvalidArgument);
  ASSERT_TRUE((*w)->Finish().ok());
  EXPECT_EQ((*w)->Write(Part(in, 0, 0, 10, 10)).code(), Status::Code::kInvalidArgument);
  Raster empty = geometry;
  empty.cols = 0;
  EXPECT_EQ(GeoTiffWriter::Create(empty, dir.Path("b.tif"), {}).status().code(),
            Status::Code::kInvalidArgument);
}

TEST(GeoTiffWriterTest, UnwrittenPixelsAreUnknownAndAnUnfinishedFileIsRemoved) {
  TempDir dir;
  const Raster in = MakeTestRaster(300, 300);
  Raster geometry = in;
  geometry.data.clear();
  {
    Result<std::unique_ptr<GeoTiffWriter>> w =
        GeoTiffWriter::Create(geometry, dir.Path("half.tif"), {});
    ASSERT_TRUE(w.ok());
    ASSERT_TRUE((*w)->Write(Part(in, 0, 0, 256, 256)).ok());
    ASSERT_TRUE((*w)->Finish().ok());
  }
  Result<Raster> half = ReadGeoTiff(dir.Path("half.tif"));
  ASSERT_TRUE(half.ok());
  EXPECT_EQ(half->data[2][100 * 300 + 100], in.data[2][100 * 300 + 100]);
  EXPECT_TRUE(std::isnan(half->data[2][280 * 300 + 280])) << "never written";
  {
    Result<std::unique_ptr<GeoTiffWriter>> w =
        GeoTiffWriter::Create(geometry, dir.Path("gone.tif"), {});
    ASSERT_TRUE(w.ok());
    ASSERT_TRUE((*w)->Write(Part(in, 0, 0, 256, 256)).ok());
  }
  EXPECT_FALSE(std::filesystem::exists(dir.Path("gone.tif")));
}

}  // namespace
}  // namespace bgkmap::io
