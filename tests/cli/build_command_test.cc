// `bgkmap build` end to end on the real Ouster street scans: the binary, its GeoTIFF and its
// errors, as a user meets them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/kitti_sequence.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;

const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

using testing::CliRun;
using testing::RunCli;
using testing::RunCommand;

class BuildCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("bgkmap_build_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(BuildCommandTest, MapsTheRealStreetScansIntoTheBandContract) {
  const CliRun run =
      RunCli("build " + kStreet + " --out " + Path("street.tif") + " --png " + Path("street.png"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("3 scans"), std::string::npos) << run.output;
  Result<Raster> r = io::ReadGeoTiff(Path("street.tif"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const std::vector<Layer> bands = {Layer::kElevation,      Layer::kElevationVariance,
                                    Layer::kTraversability, Layer::kTraversabilityVariance,
                                    Layer::kState,          Layer::kDisagreement,
                                    Layer::kBlockReason};
  EXPECT_EQ(r->layers, bands);
  EXPECT_DOUBLE_EQ(r->resolution, 0.1);
  // The same scans through the engine directly give the same values.
  auto map = std::move(TerrainMap::Create(MapParams{})).value();
  Result<io::KittiSequence> seq = io::KittiSequence::Open(kStreet);
  ASSERT_TRUE(seq.ok());
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> s = seq->Read(k);
    ASSERT_TRUE(s.ok());
    ASSERT_TRUE(map->IntegrateScan(s->points, s->pose).ok());
  }
  EXPECT_EQ(r->box, map->KnownBounds());
  int64_t known = 0, traversable = 0, compared = 0;
  const std::vector<float>& elev = *r->Find(Layer::kElevation);
  const std::vector<float>& state = *r->Find(Layer::kState);
  for (int64_t row = 0; row < r->rows; row += 7) {
    for (int64_t col = 0; col < r->cols; col += 3) {
      const CellIndex c{r->box.min.x + static_cast<int>(col), r->box.max.y - static_cast<int>(row)};
      const CellEstimate e = map->Estimate(c);
      const size_t i = static_cast<size_t>(row * r->cols + col);
      ASSERT_EQ(static_cast<float>(e.state), state[i]);
      if (std::isnan(e.elevation_weight)) {  // no data (state 0 may also be: seen too little)
        ASSERT_TRUE(std::isnan(elev[i]));
        continue;
      }
      ASSERT_FLOAT_EQ(e.elevation, elev[i]);
      ++compared;
    }
  }
  const std::vector<float>& reason = *r->Find(Layer::kBlockReason);
  for (size_t i = 0; i < state.size(); ++i) {
    known += !std::isnan(reason[i]);  // has data
    traversable += state[i] == 1.0f;
  }
  EXPECT_GT(compared, 1000);
  EXPECT_EQ(known, map->CountKnownCells());
  // A street: the road around the car is a large traversable area ~2 m below the sensor.
  EXPECT_GT(traversable, known / 4);
  const CellEstimate road = map->EstimateAt(8.0, 0.0);  // beyond the blind circle (~5 m)
  EXPECT_EQ(road.state, CellState::kTraversable);
  EXPECT_NEAR(road.elevation, -2.0, 0.5);
  EXPECT_GT(fs::file_size(Path("street.png")), 10000u);
}

TEST_F(BuildCommandTest, BboxAndMethodSelectWhatIsWritten) {
  const CliRun run = RunCli("build " + kStreet + " --out " + Path("crop.tif") +
                            " --method baseline --bbox -10,-5,10,5");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("method baseline"), std::string::npos);
  Result<Raster> r = io::ReadGeoTiff(Path("crop.tif"));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->cols, 200);
  EXPECT_EQ(r->rows, 100);
  EXPECT_DOUBLE_EQ(r->x0, -10.0);
  EXPECT_DOUBLE_EQ(r->y1, 5.0);
}

TEST_F(BuildCommandTest, BadInputsFailWithOneClearLine) {
  std::ofstream(Path("bad.yaml")) << "resolution: -1\n";
  std::ofstream(Path("typo.yaml")) << "kernel_lenght: 0.3\n";
  fs::create_directories(Path("seq/velodyne"));
  std::ofstream(Path("seq/velodyne/000000.bin")) << "12345";  // not a multiple of 16 bytes
  std::ofstream(Path("seq/poses.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  struct Case {
    std::string args, must_mention;
    int exit_code;  // 1: failure (files, configuration), 2: a bad command line
  };
  const std::vector<Case> cases = {
      {"build /nonexistent --out x.tif", "/nonexistent", 1},
      {"build " + kStreet + " --config " + Path("bad.yaml") + " --out x.tif", "resolution", 1},
      {"build " + kStreet + " --config " + Path("typo.yaml") + " --out x.tif", "kernel_lenght", 1},
      {"build " + kStreet + " --method fancy --out x.tif", "method", 2},
      {"build " + kStreet + " --bbox 5,5,1,1 --out x.tif", "--bbox", 2},
      {"build " + Path("seq") + " --out " + Path("x.tif"), "000000.bin", 1},
      {"build " + kStreet + " --out /nonexistent/dir/x.tif", "/nonexistent/dir/x.tif", 1},
  };
  for (const Case& c : cases) {
    const CliRun run = RunCli(c.args);
    EXPECT_EQ(run.exit_code, c.exit_code) << c.args;
    EXPECT_NE(run.output.find(c.must_mention), std::string::npos) << c.args << "\n" << run.output;
    // One line: the error, not a stack of GDAL chatter or a usage dump.
    EXPECT_LE(std::count(run.output.begin(), run.output.end(), '\n'), 4) << run.output;
  }
}

TEST_F(BuildCommandTest, MapsTheAirborneLasGroundPointsAsOneCloud) {
  const CliRun run = RunCli("build " + std::string(BGKMAP_SHARED_DATA) +
                            "/als_topography/topography.las --classes 2 --out " + Path("als.tif"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("8159 points"), std::string::npos) << run.output;
  // The GeoTIFF is in the LAS file's CRS (its GeoKeyDirectory: EPSG:2949), as gdalinfo shows.
  const CliRun info = RunCommand("gdalinfo " + Path("als.tif") + " 2>&1");
  EXPECT_NE(info.output.find("ID[\"EPSG\",2949]"), std::string::npos) << info.output;
  EXPECT_EQ(info.output.find("LAYOUT=COG"), std::string::npos);
}

TEST_F(BuildCommandTest, CogAndCrsOnRequest) {
  const CliRun run = RunCli("build " + kStreet + " --cog --crs EPSG:32610 --out " + Path("s.tif"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CliRun info = RunCommand("gdalinfo " + Path("s.tif") + " 2>&1");
  EXPECT_NE(info.output.find("LAYOUT=COG"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("ID[\"EPSG\",32610]"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("Overviews"), std::string::npos) << info.output;
  Result<Raster> r = io::ReadGeoTiff(Path("s.tif"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->layers.size(), 7u);
  const CliRun bad = RunCli("build " + kStreet + " --crs EPSG:nonsense --out " + Path("b.tif"));
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("unknown spatial reference"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace bgkmap
