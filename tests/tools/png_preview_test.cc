#include "bgkmap/io/png_preview.h"

#include <gtest/gtest.h>
#include <png.h>

#include <cstring>

#include "raster_fixture.h"
#include "test_files.h"

namespace bgkmap::io {
namespace {

using testing::MakeTestRaster;
using testing::TempDir;

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
  std::array<int, 3> At(int x, int y) const {
    const size_t i = (static_cast<size_t>(y) * width + x) * 3;
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

// Decodes with libpng itself: a file it accepts is a valid PNG.
Image ReadPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  Image img;
  if (!png_image_begin_read_from_file(&png, path.c_str())) {
    ADD_FAILURE() << path << ": " << png.message;
    return img;
  }
  EXPECT_EQ(png.format & PNG_FORMAT_FLAG_COLOR, PNG_FORMAT_FLAG_COLOR);
  png.format = PNG_FORMAT_RGB;
  img.width = static_cast<int>(png.width);
  img.height = static_cast<int>(png.height);
  img.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, img.rgb.data(), 0, nullptr)) {
    ADD_FAILURE() << path << ": " << png.message;
  }
  return img;
}

TEST(PngPreviewTest, GeometryUpscalesSmallAndCapsLargeRasters) {
  PreviewGeometry small = ComputePreviewGeometry(40, 30);
  EXPECT_EQ(small.panel_width % 40, 0);  // integer upscaling keeps pixels square and crisp
  EXPECT_GE(small.image_width, 600);
  EXPECT_EQ(small.panel_height * 40, small.panel_width * 30);
  PreviewGeometry big = ComputePreviewGeometry(5000, 100);
  EXPECT_LE(big.panel_width, 2048);
  EXPECT_GE(big.panel_height, 40);
  PreviewGeometry tall = ComputePreviewGeometry(10, 1000);
  EXPECT_LE(tall.panel_height, 2048);
  PreviewGeometry medium = ComputePreviewGeometry(700, 500);
  EXPECT_EQ(medium.panel_width, 700);
  EXPECT_EQ(medium.panel_height, 500);
}

TEST(PngPreviewTest, WritesAReadablePanelledImage) {
  TempDir dir;
  const Raster raster = MakeTestRaster(40, 30);
  const std::string path = dir.Path("preview.png");
  Status s = WritePreviewPng(raster, path);
  ASSERT_TRUE(s.ok()) << s.message();

  const std::string bytes = testing::ReadBytes(path);
  ASSERT_GT(bytes.size(), 8u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));

  const PreviewGeometry g = ComputePreviewGeometry(40, 30);
  const Image img = ReadPng(path);
  ASSERT_EQ(img.width, g.image_width);
  ASSERT_EQ(img.height, g.image_height);
  const int scale = g.panel_width / 40;
  const int right = g.panel_width + (g.image_width - 2 * g.panel_width);
  auto centre = [&](int col, int row, bool right_panel) {
    return img.At((right_panel ? right : 0) + col * scale + scale / 2, row * scale + scale / 2);
  };

  // Unknown cells: dark grey on the left, black on the right.
  EXPECT_EQ(centre(2, 2, false), (std::array<int, 3>{64, 64, 64}));
  EXPECT_EQ(centre(2, 2, true), (std::array<int, 3>{0, 0, 0}));
  EXPECT_EQ(centre(20, 15, true), (std::array<int, 3>{0, 0, 0}));  // the unknown row
  // Traversable west edge is green; the non-traversable east edge is red (and tinted).
  const auto west = centre(0, 25, true);
  EXPECT_GT(west[1], 120);
  EXPECT_LT(west[0], 60);
  const auto east = centre(39, 25, true);
  EXPECT_GT(east[0], 200);
  EXPECT_LT(east[1], 40);
  // Known elevation is coloured, neither unknown grey nor black.
  const auto elev = centre(30, 25, false);
  EXPECT_NE(elev, (std::array<int, 3>{64, 64, 64}));
  EXPECT_GT(elev[0] + elev[1] + elev[2], 100);
  // The legend labels are drawn in light text below the bars.
  int text_pixels = 0;
  for (int y = g.panel_height + 16; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x)
      text_pixels += img.At(x, y) == std::array<int, 3>{235, 235, 235};
  }
  EXPECT_GT(text_pixels, 100);
  // The separator is a light column between the panels.
  EXPECT_EQ(img.At(g.panel_width + 1, 10), (std::array<int, 3>{220, 220, 220}));
}

TEST(PngPreviewTest, StateTintsNonTraversableCells) {
  TempDir dir;
  Raster raster = MakeTestRaster(40, 30);
  const std::string plain = dir.Path("plain.png"), tinted = dir.Path("tinted.png");
  raster.data[3].assign(raster.data[3].size(), 1.0f);  // all traversable: no tint
  ASSERT_TRUE(WritePreviewPng(raster, plain).ok());
  raster.data[3].assign(raster.data[3].size(), 2.0f);  // all non-traversable
  ASSERT_TRUE(WritePreviewPng(raster, tinted).ok());
  const Image a = ReadPng(plain), b = ReadPng(tinted);
  const PreviewGeometry g = ComputePreviewGeometry(40, 30);
  const int x = g.image_width - g.panel_width + 5, y = g.panel_height - 5;  // a green cell
  EXPECT_GT(b.At(x, y)[0], a.At(x, y)[0] + 80);
  EXPECT_LT(b.At(x, y)[1], a.At(x, y)[1]);
}

TEST(PngPreviewTest, Errors) {
  TempDir dir;
  Raster empty;
  EXPECT_EQ(WritePreviewPng(empty, dir.Path("a.png")).code(), Status::Code::kInvalidArgument);
  Raster no_layers = MakeTestRaster(4, 4);
  no_layers.layers = {Layer::kElevationVariance};
  no_layers.data.resize(1);
  EXPECT_EQ(WritePreviewPng(no_layers, dir.Path("b.png")).code(), Status::Code::kInvalidArgument);
  const std::string unwritable = dir.Path("no/such/dir/c.png");
  Status s = WritePreviewPng(MakeTestRaster(4, 4), unwritable);
  EXPECT_EQ(s.code(), Status::Code::kIoError);
  EXPECT_EQ(s.message().rfind(unwritable + ": ", 0), 0u) << s.message();
}

}  // namespace
}  // namespace bgkmap::io
