// `bgkmap insert --align-z` against a real bgkmapd (docs/mapping-your-robot.md, "Vertical
// alignment"): a scan sent with a z error is aligned to the served map before it is sent, so the
// map is the map of the scans without the error.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "bgkmap/io/geotiff.h"
#include "bgkmapd_process.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

// The Ouster street's three scans with `dz` added to scan 1's pose z and its sensor turned by
// `pitch_deg` about the map's y axis (a pitch error of a car heading along x).
fs::path StreetWithPoseError(const fs::path& dir, double dz, double pitch_deg = 0.0) {
  fs::create_directories(dir / "velodyne");
  for (const char* scan : {"000000.bin", "000001.bin", "000002.bin"}) {
    fs::copy_file(fs::path(kStreet) / "velodyne" / scan, dir / "velodyne" / scan);
  }
  std::ifstream in(fs::path(kStreet) / "poses.txt");
  std::ofstream out(dir / "poses.txt");
  std::string line;
  for (int k = 0; std::getline(in, line); ++k) {
    std::istringstream fields(line);
    double v[12];
    for (double& x : v) fields >> x;
    if (k == 1) {
      v[11] += dz;  // row 3's translation: z
      // R' = Ry R: rows 1 and 3 of the rotation (x and z) mix, the translation stays.
      const double a = pitch_deg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
      for (int col = 0; col < 3; ++col) {
        const double x = v[col], z = v[8 + col];
        v[col] = c * x + s * z;
        v[8 + col] = -s * x + c * z;
      }
    }
    out.precision(17);
    for (int i = 0; i < 12; ++i) out << v[i] << (i < 11 ? ' ' : '\n');
  }
  return dir;
}

// The elevation GeoTIFF of everything `insert ARGS` maps on a fresh server.
Raster ServedElevation(const std::string& insert_args, const fs::path& tif, std::string* output) {
  testing::BgkmapdProcess server(std::vector<std::string>{});
  EXPECT_TRUE(server.started());
  const std::string s = " --server " + server.target();
  const testing::CliRun run = testing::RunCli("insert " + insert_args + s, "2>/dev/null");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  *output = run.output;
  EXPECT_EQ(testing::RunCli("query --bbox -40,-40,40,40 --out " + tif.string() + s, "2>/dev/null")
                .exit_code,
            0);
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(), 0);
  Result<Raster> r = io::ReadGeoTiff(tif.string());
  EXPECT_TRUE(r.ok());
  return r.ok() ? *r : Raster{};
}

// The differences of elevation over the cells both rasters know, sorted by size.
std::vector<double> ElevationDifferences(const Raster& a, const Raster& b) {
  const std::vector<float>* ea = a.Find(Layer::kElevation);
  const std::vector<float>* eb = b.Find(Layer::kElevation);
  std::vector<double> d;
  if (ea == nullptr || eb == nullptr || a.box != b.box) return d;
  for (size_t i = 0; i < ea->size(); ++i) {
    if (std::isnan((*ea)[i]) || std::isnan((*eb)[i])) continue;
    d.push_back(std::abs(static_cast<double>((*ea)[i]) - (*eb)[i]));
  }
  std::sort(d.begin(), d.end());
  return d;
}

double Quantile(const std::vector<double>& sorted, double q) {
  return sorted.empty() ? INFINITY : sorted[static_cast<size_t>(q * (sorted.size() - 1))];
}

TEST(AlignZTest, AScanWithA10CmZErrorMapsAsWithoutIt) {
  const fs::path dir = fs::temp_directory_path() / ("bgkmap_align_z_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path wrong = StreetWithPoseError(dir / "street_dz", 0.10);
  std::string out;
  const Raster truth = ServedElevation(kStreet + " --robot r", dir / "truth.tif", &out);
  const Raster plain = ServedElevation(wrong.string() + " --robot r", dir / "plain.tif", &out);
  const Raster truth_aligned =
      ServedElevation(kStreet + " --robot r --align-z", dir / "truth_aligned.tif", &out);
  const Raster aligned =
      ServedElevation(wrong.string() + " --robot r --align-z", dir / "aligned.tif", &out);
  // Scan 0 meets an empty map; scans 1 and 2 are aligned.
  EXPECT_NE(out.find("--align-z: 2 scans aligned"), std::string::npos) << out;
  std::printf("%s", out.c_str());
  const std::vector<double> before = ElevationDifferences(plain, truth);
  const std::vector<double> after = ElevationDifferences(aligned, truth);
  const std::vector<double> both = ElevationDifferences(aligned, truth_aligned);
  ASSERT_GT(before.size(), 100000u);
  ASSERT_GT(after.size(), 100000u);
  ASSERT_GT(both.size(), 100000u);
  // Without the alignment the error is in the map: scan 1's cells 10 cm off.
  EXPECT_GT(Quantile(before, 0.9), 0.09);
  // With it, the map is the one the true poses give when aligned the same way, to the bit
  // (the offset moves the median by exactly the error) ...
  EXPECT_LT(Quantile(both, 1.0), 1e-4);
  // ... and within a few mm of the true poses' map: the alignment also moves the true-pose
  // scans 1 and 2 by their own median offsets (mm: the sequence's poses disagree that much).
  // The last 1 % holds cells whose free-space evidence changes with a few mm of height.
  EXPECT_LT(Quantile(after, 0.5), 0.003);
  EXPECT_LT(Quantile(after, 0.99), 0.01);
  std::printf("|elevation - truth|, median / 99 %%: %.4f / %.4f m without, %.4f / %.4f m with\n",
              Quantile(before, 0.5), Quantile(before, 0.99), Quantile(after, 0.5),
              Quantile(after, 0.99));
  fs::remove_all(dir);
}

// --align-tilt (docs/mapping-your-robot.md, "Levelling the tilt"): a scan whose pose is pitched
// 0.3 deg (10 cm at 20 m, the roll and pitch error of a lidar-only localization) is levelled
// against the served map before it is sent, and maps as the true pose levelled does.
TEST(AlignZTest, AScanPitchedBy03DegMapsAsWithoutItWhenLevelled) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_align_tilt_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path wrong = StreetWithPoseError(dir / "street_pitch", 0.0, 0.3);
  std::string out;
  const Raster truth = ServedElevation(kStreet + " --robot r", dir / "truth.tif", &out);
  const Raster offset =
      ServedElevation(wrong.string() + " --robot r --align-z", dir / "offset.tif", &out);
  const Raster truth_levelled = ServedElevation(kStreet + " --robot r --align-z --align-tilt 1",
                                                dir / "truth_levelled.tif", &out);
  const Raster levelled = ServedElevation(wrong.string() + " --robot r --align-z --align-tilt 1",
                                          dir / "levelled.tif", &out);
  EXPECT_NE(out.find("--align-tilt: 2 scans levelled"), std::string::npos) << out;
  std::printf("%s", out.c_str());
  const std::vector<double> before = ElevationDifferences(offset, truth);
  const std::vector<double> after = ElevationDifferences(levelled, truth);
  const std::vector<double> both = ElevationDifferences(levelled, truth_levelled);
  ASSERT_GT(before.size(), 100000u);
  ASSERT_GT(after.size(), 100000u);
  ASSERT_GT(both.size(), 100000u);
  // An offset alone cannot take a tilt out: the far cells stay centimetres off ...
  EXPECT_GT(Quantile(before, 0.9), 0.05);
  // ... levelled, the map is the one the true poses give when levelled the same way, within
  // millimetres (the fitted plane is not exactly linear in the error) ...
  EXPECT_LT(Quantile(both, 0.5), 0.001);
  EXPECT_LT(Quantile(both, 0.99), 0.005);
  // ... and nearer the true poses' unlevelled map than the offset alone: levelling also turns
  // the true scans 1 and 2, by the ~0.1 deg their own poses' tilts disagree.
  EXPECT_LT(Quantile(after, 0.9), 0.5 * Quantile(before, 0.9));
  std::printf(
      "|elevation - truth|, median / 90 %% / 99 %%: %.4f / %.4f / %.4f m offset only, "
      "%.4f / %.4f / %.4f m levelled\n",
      Quantile(before, 0.5), Quantile(before, 0.9), Quantile(before, 0.99), Quantile(after, 0.5),
      Quantile(after, 0.9), Quantile(after, 0.99));
  std::printf("levelled against the true poses levelled: %.4f / %.4f / %.4f m\n",
              Quantile(both, 0.5), Quantile(both, 0.9), Quantile(both, 0.99));
  fs::remove_all(dir);
}

// Tilt without the offset it levels is a usage error, before anything is sent.
TEST(AlignZTest, AlignTiltWithoutAlignZIsAUsageError) {
  const testing::CliRun run = testing::RunCli("insert " + kStreet + " --align-tilt 1", "2>&1");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("--align-tilt levels what --align-z compares"), std::string::npos)
      << run.output;
}

}  // namespace
}  // namespace bgkmap
