// `bgkmap build`'s GeoTIFF written strip by strip on threads (tools/bgkmap/map_geotiff.h): the
// same pixels, georeferencing and bands as the whole raster written at once, whatever the threads,
// for a raster of several strips, a box wider than the known cells, and a COG.
//
// Mutation checked: strips one row short (`top - strip_rows + 2` as a strip's bottom row) leave a
// row of unknown pixels between strips, and the comparison fails.
#include "map_geotiff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "bgkmap/io/geotiff.h"

namespace bgkmap::cli {
namespace {

namespace fs = std::filesystem;

const std::vector<Layer> kLayers = {Layer::kElevation, Layer::kTraversability, Layer::kState};

// A 12 x 60 m sloped street with a kerb and a box on it, one point per 0.1 m cell: 600 rows of
// cells, three strips of GeoTIFF blocks.
std::unique_ptr<TerrainMap> StreetMap() {
  MapParams p;
  p.min_range = 0;
  p.max_height_above_sensor = 100;
  auto map = std::move(TerrainMap::Create(p)).value();
  std::vector<Point3f> points;
  for (int ix = 0; ix < 120; ++ix) {
    for (int iy = -300; iy < 300; ++iy) {
      const float x = (ix + 0.5f) * 0.1f, y = (iy + 0.5f) * 0.1f;
      float z = 0.02f * y + (ix > 100 ? 0.15f : 0.0f);
      if (ix > 40 && ix < 60 && iy > 10 && iy < 40) z += 1.0f;
      points.push_back({x, y, z});
    }
  }
  EXPECT_TRUE(map->IntegrateScan(points, Pose{}, /*frame_is_map=*/true).ok());
  return map;
}

class MapGeoTiffTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() /
        ("map_geotiff_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

// Bit for bit, NaN included.
void ExpectSameRaster(const Raster& a, const Raster& b) {
  ASSERT_EQ(a.cols, b.cols);
  ASSERT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.x0, b.x0);
  EXPECT_EQ(a.y1, b.y1);
  EXPECT_EQ(a.resolution, b.resolution);
  ASSERT_EQ(a.layers, b.layers);
  ASSERT_EQ(a.data.size(), b.data.size());
  for (size_t l = 0; l < a.data.size(); ++l) {
    ASSERT_EQ(a.data[l].size(), b.data[l].size());
    EXPECT_EQ(std::memcmp(a.data[l].data(), b.data[l].data(), a.data[l].size() * sizeof(float)), 0)
        << "layer " << LayerName(a.layers[l]);
  }
}

TEST_F(MapGeoTiffTest, StripsOnThreadsWriteTheWholeRastersPixels) {
  const auto map = StreetMap();
  CellBox box = map->KnownBounds();
  ASSERT_GT(box.height(), 2 * 256);
  box.min.x -= 7;  // unknown pixels around the known ones
  box.max.y += 9;
  const Raster whole = ExtractRaster(*map, box, kLayers);
  io::GeoTiffOptions tiff;
  ASSERT_TRUE(io::WriteGeoTiff(whole, Path("whole.tif"), tiff).ok());
  Result<Raster> expected = io::ReadGeoTiff(Path("whole.tif"));
  ASSERT_TRUE(expected.ok()) << expected.status().message();
  int known = 0;
  for (float v : expected->data[0]) known += std::isnan(v) ? 0 : 1;
  EXPECT_GT(known, 50'000);
  for (int threads : {1, 3}) {
    const std::string path = Path("strips" + std::to_string(threads) + ".tif");
    ASSERT_TRUE(WriteMapGeoTiff(*map, box, kLayers, path, tiff, threads).ok());
    Result<Raster> got = io::ReadGeoTiff(path);
    ASSERT_TRUE(got.ok()) << got.status().message();
    SCOPED_TRACE("threads " + std::to_string(threads));
    ExpectSameRaster(*expected, *got);
  }
  tiff.cloud_optimized = true;
  ASSERT_TRUE(WriteMapGeoTiff(*map, box, kLayers, Path("cog.tif"), tiff, 2).ok());
  Result<Raster> cog = io::ReadGeoTiff(Path("cog.tif"));
  ASSERT_TRUE(cog.ok()) << cog.status().message();
  ExpectSameRaster(*expected, *cog);
  EXPECT_FALSE(fs::exists(Path("cog.tif.staging.tif")));
}

TEST_F(MapGeoTiffTest, AnUnwritableFileIsAnErrorNamingIt) {
  const auto map = StreetMap();
  const std::string path = Path("missing/dir/x.tif");
  const Status s =
      WriteMapGeoTiff(*map, map->KnownBounds(), kLayers, path, io::GeoTiffOptions{}, 2);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
}

}  // namespace
}  // namespace bgkmap::cli
