// `bgkmap build` end to end on the real Ouster street scans: the binary, its GeoTIFF and its
// errors, as a user meets them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
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
  const CliRun run =
      RunCli("build " + kStreet + " --cog --crs EPSG:32610 --origin 551000,4180000 " + "--out " +
             Path("s.tif"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CliRun info = RunCommand("gdalinfo " + Path("s.tif") + " 2>&1");
  EXPECT_NE(info.output.find("LAYOUT=COG"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("ID[\"EPSG\",32610]"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("Overviews"), std::string::npos) << info.output;
  Result<Raster> r = io::ReadGeoTiff(Path("s.tif"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->layers.size(), 7u);
  EXPECT_DOUBLE_EQ(r->x0, r->box.min.x * r->resolution + 551000);  // placed by --origin
}

// What QGIS needs to show traversability rather than three float bands as RGB: every band named
// and with NoData, and the style beside the file (s.qml, loaded as the layer's default) drawing
// the traversability band, the third, with its colour ramp.
TEST_F(BuildCommandTest, GeoTiffCarriesBandNamesNoDataAndAQgisStyle) {
  const CliRun run = RunCli("-q build " + kStreet + " --out " + Path("s.tif"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CliRun info = RunCommand("gdalinfo " + Path("s.tif") + " 2>&1");
  for (const char* name : {"elevation", "elevation_variance", "traversability",
                           "traversability_variance", "state", "disagreement", "block_reason"}) {
    EXPECT_NE(info.output.find(std::string("Description = ") + name + "\n"), std::string::npos)
        << name << "\n"
        << info.output;
  }
  size_t nodata = 0;
  for (size_t at = info.output.find("NoData Value=nan"); at != std::string::npos;
       at = info.output.find("NoData Value=nan", at + 1)) {
    ++nodata;
  }
  EXPECT_EQ(nodata, 7u) << info.output;
  std::ifstream in(Path("s.qml"));
  const std::string qml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(qml.find("type=\"singlebandpseudocolor\" band=\"3\""), std::string::npos) << qml;
  EXPECT_NE(qml.find("1 not traversable"), std::string::npos) << qml;
  // Well-formed XML (QGIS ignores a style it cannot parse).
  EXPECT_EQ(
      RunCommand("/usr/bin/python3 -c 'import sys, xml.dom.minidom as m; m.parse(sys.argv[1])' " +
                 Path("s.qml") + " 2>&1")
          .exit_code,
      0);
}

// Georeferencing is checked before any scan is read (no progress line), with exit 2: an unknown
// CRS, a geographic one on a metric map, and a projected one on a local frame without --origin
// (which would put the street on the equator at the CRS's false origin).
TEST_F(BuildCommandTest, GeoreferenceIsCheckedBeforeAnyWork) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--crs EPSG:nonsense", "not a coordinate system GDAL knows"},
      {"--crs EPSG:4326 --origin 0,0", "is geographic (degrees)"},
      {"--crs EPSG:32610", "the map frame is local"},
      {"--origin 1,2", "pass --crs too"},
      {"--crs EPSG:32610 --origin 1", "--origin: expected E,N or E,N,H"}};
  for (const auto& [args, message] : cases) {
    const CliRun bad = RunCli("build " + kStreet + " " + args + " --out " + Path("b.tif"));
    EXPECT_EQ(bad.exit_code, 2) << args << "\n" << bad.output;
    EXPECT_NE(bad.output.find(message), std::string::npos) << args << "\n" << bad.output;
    EXPECT_EQ(bad.output.find("mapping"), std::string::npos) << args << "\n" << bad.output;
    EXPECT_FALSE(fs::exists(Path("b.tif"))) << args;
  }
  // A cloud in its own coordinates (LAS, PCD) is not local: a projected CRS needs no origin.
  const std::string las = std::string(BGKMAP_SHARED_DATA) + "/als_topography/topography.las";
  const CliRun las_run =
      RunCli("build " + las + " --classes 2 --crs EPSG:2949 --out " + Path("l.tif"));
  EXPECT_EQ(las_run.exit_code, 0) << las_run.output;
}

// `--out x.png` writes the picture its name asks for; a format bgkmap does not write is a usage
// error before any work; --quiet (anywhere on the line) prints no progress.
TEST_F(BuildCommandTest, OutputNamesAndQuiet) {
  const CliRun png = RunCli("build " + kStreet + " --quiet --out " + Path("s.png"));
  ASSERT_EQ(png.exit_code, 0) << png.output;
  EXPECT_EQ(png.output.find("mapping "), std::string::npos) << png.output;
  std::ifstream in(Path("s.png"), std::ios::binary);
  std::string magic(8, '\0');
  in.read(magic.data(), 8);
  EXPECT_EQ(magic, std::string("\x89PNG\r\n\x1a\n", 8));
  const CliRun noisy = RunCli("build " + kStreet + " --out " + Path("s.tif"));
  EXPECT_NE(noisy.output.find("mapping "), std::string::npos) << noisy.output;
  const CliRun jpg = RunCli("-q build " + kStreet + " --out " + Path("s.jpg"));
  EXPECT_EQ(jpg.exit_code, 2) << jpg.output;
  EXPECT_NE(jpg.output.find("writes a GeoTIFF (.tif), a PNG preview (.png)"), std::string::npos)
      << jpg.output;
}

// The same bits in every band (NaN, unknown, matches NaN: a GeoTIFF need not keep its payload).
bool SameBits(const Raster& a, const Raster& b) {
  if (a.box != b.box || a.layers != b.layers || a.data.size() != b.data.size()) return false;
  for (size_t i = 0; i < a.data.size(); ++i) {
    if (a.data[i].size() != b.data[i].size()) return false;
    for (size_t j = 0; j < a.data[i].size(); ++j) {
      const float x = a.data[i][j], y = b.data[i][j];
      if (std::isnan(x) != std::isnan(y)) return false;
      if (!std::isnan(x) && std::memcmp(&x, &y, sizeof x) != 0) return false;
    }
  }
  return true;
}

// The scans through the engine one by one, as the server integrates them.
Raster EngineRaster(const std::string& dir) {
  auto map = std::move(TerrainMap::Create(MapParams{})).value();
  io::KittiSequence seq = std::move(io::KittiSequence::Open(dir)).value();
  for (size_t k = 0; k < seq.size(); ++k) {
    io::Scan s = std::move(seq.Read(k)).value();
    EXPECT_TRUE(map->IntegrateScan(s.points, s.pose).ok());
  }
  return ExtractRaster(
      *map, map->KnownBounds(),
      {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability,
       Layer::kTraversabilityVariance, Layer::kState, Layer::kDisagreement, Layer::kBlockReason});
}

// Scans prepared in parallel and the map integrated in bands, one per thread: the same map bit
// for bit as the engine's scan by scan, on the KITTI drive (one and two bands) and on the street
// cut into four (three band borders through the densest cells). Mutation caught: a halo one
// kernel length short, or a band's tiles taken from its neighbour's map (cells near the borders
// differ).
TEST_F(BuildCommandTest, ThreadsGiveTheSameMapBitForBit) {
  const std::string kitti = std::string(BGKMAP_SHARED_DATA) + "/kitti_raw_0048";
  for (const std::string& input : {kitti, kStreet}) {
    const Raster engine = EngineRaster(input);
    for (int threads : input == kitti ? std::vector<int>{1, 2} : std::vector<int>{4}) {
      // (Built step by step: GCC 12's -Wrestrict misfires on "t" + std::to_string(...).)
      std::string name = std::to_string(threads);
      name.append(".tif");
      const std::string out = Path(name);
      const CliRun run =
          RunCli("-q build " + input + " --threads " + std::to_string(threads) + " --out " + out);
      ASSERT_EQ(run.exit_code, 0) << run.output;
      Result<Raster> r = io::ReadGeoTiff(out);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      EXPECT_TRUE(SameBits(engine, *r)) << input << " on " << threads << " threads";
    }
  }
}

// The car's profile (transient objects on; the KITTI drive has no times.txt, so it is taken at
// 10 Hz): the bands' restrictions see the whole scan's cells for the sight test, shared with the
// scan rather than copied, and two bands give the one band's map bit for bit.
TEST_F(BuildCommandTest, TransientObjectsGiveTheSameMapOnTwoThreads) {
  const std::string kitti = std::string(BGKMAP_SHARED_DATA) + "/kitti_raw_0048";
  const std::string config = std::string(BGKMAP_SOURCE_DIR) + "/experiments/robots/car_kitti.yaml";
  std::vector<Raster> maps;
  for (int threads : {1, 2}) {
    std::string name = "transients";
    name.append(std::to_string(threads)).append(".tif");
    const CliRun run = RunCli("-q build " + kitti + " --config " + config + " --threads " +
                              std::to_string(threads) + " --out " + Path(name));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    Result<Raster> r = io::ReadGeoTiff(Path(name));
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    maps.push_back(std::move(r).value());
  }
  EXPECT_TRUE(SameBits(maps[0], maps[1]));
}

// A stray point 1000 km from a small cloud (a bad GPS fix in a survey): the cut, which counts
// cells per coordinate along the map, would need 10^7 of them; such a map is integrated as one
// band, the same map on 2 threads as on 1.
TEST_F(BuildCommandTest, StrayFarPointIsMappedAsOneBand) {
  std::ofstream pcd(Path("stray.pcd"));
  std::string points;
  int n = 0;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j, ++n) {
      points += std::to_string(0.05 * i) + " " + std::to_string(0.05 * j) + " 0.1\n";
    }
  }
  points += "1000000 3 0.2\n";
  ++n;
  pcd << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << n
      << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\nDATA ascii\n"
      << points;
  pcd.close();
  std::string bytes[2];
  for (int threads : {1, 2}) {
    std::string name = std::to_string(threads);
    name.append(".tif");
    const CliRun run = RunCli("-q build " + Path("stray.pcd") + " --threads " +
                              std::to_string(threads) + " --bbox -1,-1,3,3 --out " + Path(name));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    std::ifstream in(Path(name), std::ios::binary);
    bytes[threads - 1].assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_FALSE(bytes[0].empty());
  EXPECT_TRUE(bytes[0] == bytes[1]);
}

}  // namespace
}  // namespace bgkmap
