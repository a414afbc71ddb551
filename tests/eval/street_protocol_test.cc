// The street evaluation protocol's commands end to end through the CLI (docs/results.md, "Real
// street scans (issue 14 protocol)"): `bgkmap thin` keeps exactly the records i % N == offset of
// each scan file, bytes and intensity unchanged, and only the scans asked for, with their poses
// and times; `bgkmap truth` writes a ground truth in the simulator's band layout that
// `bgkmap eval --truth` scores a thinned copy against.
// Mutations checked once by hand: thin stepping by 1 instead of N (i += 1) fails
// KeepsExactlyEveryNthRecord; thin ignoring --offset (i starting at 0) fails
// OffsetAndScansPickRecordsAndScans.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../cli/cli_runner.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/kitti_sequence.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

std::vector<char> Bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::string> Lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

nlohmann::json Json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in, nullptr, false);
}

class StreetProtocolTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("bgkmap_street_protocol_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "seq" / "velodyne");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Scan k: `n` points with distinct coordinates and intensities, the sensor 2 m above z = 0
  // ground points on a grid of spacing 0.05 m (4 per 0.1 m cell) around it, at x offset k / 10.
  void WriteSequence(int scans, int n) {
    for (int k = 0; k < scans; ++k) {
      std::vector<Point3f> points;
      std::vector<float> intensity;
      const int side = static_cast<int>(std::ceil(std::sqrt(n)));
      for (int i = 0; i < n; ++i) {
        const float x = -2.0f + 0.05f * static_cast<float>(i % side);
        const float y = -2.0f + 0.05f * static_cast<float>(i / side);
        points.push_back({x + 0.001f * static_cast<float>(k), y, -2.0f});
        intensity.push_back(static_cast<float>(1000 * k + i));
      }
      ASSERT_TRUE(
          io::WriteKittiScan((dir_ / "seq" / "velodyne" / io::KittiScanFileName(k)).string(),
                             points, intensity)
              .ok());
      Pose pose;
      pose.translation = {0.1 * k, 0.0, 2.0};
      ASSERT_TRUE(io::AppendPose((dir_ / "seq" / "poses.txt").string(), pose).ok());
      std::ofstream(dir_ / "seq" / "times.txt", std::ios::app) << 0.1 * k << "\n";
    }
  }

  fs::path dir_;
};

TEST_F(StreetProtocolTest, KeepsExactlyEveryNthRecord) {
  WriteSequence(2, 100);
  const CliRun run = RunCli("thin " + (dir_ / "seq").string() + " --keep-every 3 --out " +
                            (dir_ / "thin").string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (int k = 0; k < 2; ++k) {
    const std::vector<char> in = Bytes(dir_ / "seq" / "velodyne" / io::KittiScanFileName(k));
    const std::vector<char> out = Bytes(dir_ / "thin" / "velodyne" / io::KittiScanFileName(k));
    ASSERT_EQ(out.size(), 34u * 16);  // indices 0, 3, ..., 99
    for (size_t j = 0; j < 34; ++j) {
      EXPECT_EQ(std::memcmp(out.data() + 16 * j, in.data() + 16 * (3 * j), 16), 0) << j;
    }
  }
  EXPECT_EQ(Lines(dir_ / "thin" / "poses.txt"), Lines(dir_ / "seq" / "poses.txt"));
  const nlohmann::json j = Json(dir_ / "thin" / "thin.json");
  EXPECT_EQ(j["points_in"], 200);
  EXPECT_EQ(j["points_out"], 68);
}

TEST_F(StreetProtocolTest, OffsetAndScansPickRecordsAndScans) {
  WriteSequence(3, 10);
  const CliRun run =
      RunCli("thin " + (dir_ / "seq").string() + " --keep-every 4 --offset 1 --scans 2,0 --out " +
             (dir_ / "thin").string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Result<io::KittiSequence> thin = io::KittiSequence::Open((dir_ / "thin").string());
  ASSERT_TRUE(thin.ok()) << thin.status().message();
  ASSERT_EQ(thin->size(), 2u);
  Result<io::KittiSequence> seq = io::KittiSequence::Open((dir_ / "seq").string());
  ASSERT_TRUE(seq.ok());
  const int source[] = {2, 0};
  for (size_t j = 0; j < 2; ++j) {
    Result<io::Scan> out = thin->Read(j);
    Result<io::Scan> in = seq->Read(static_cast<size_t>(source[j]));
    ASSERT_TRUE(out.ok() && in.ok());
    ASSERT_EQ(out->points.size(), 3u);  // indices 1, 5, 9
    for (size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(out->points[i].x, in->points[1 + 4 * i].x);
      EXPECT_EQ(out->points[i].y, in->points[1 + 4 * i].y);
    }
    EXPECT_EQ(out->pose.translation, in->pose.translation);
    EXPECT_EQ(out->time_s, in->time_s);
  }
  // The intensity survives: record 1 of scan 2 has intensity 2001.
  const std::vector<char> bytes = Bytes(dir_ / "thin" / "velodyne" / io::KittiScanFileName(0));
  float intensity = 0;
  std::memcpy(&intensity, bytes.data() + 12, 4);
  EXPECT_EQ(intensity, 2001.0f);
}

TEST_F(StreetProtocolTest, BadArgumentsAreUsageErrors) {
  WriteSequence(1, 10);
  EXPECT_EQ(RunCli("thin " + (dir_ / "seq").string() + " --keep-every 2 --offset 2 --out " +
                   (dir_ / "a").string())
                .exit_code,
            2);
  EXPECT_EQ(RunCli("thin " + (dir_ / "seq").string() + " --keep-every 2 --scans 1 --out " +
                   (dir_ / "b").string())
                .exit_code,
            2);
  EXPECT_EQ(
      RunCli("thin " + (dir_ / "seq").string() + " --keep-every 0 --out " + (dir_ / "c").string())
          .exit_code,
      2);
}

TEST_F(StreetProtocolTest, TruthFromAllScansScoresAThinnedCopy) {
  WriteSequence(3, 6400);  // 4 m x 4 m of ground, 4 points per cell per scan
  const std::string seq = (dir_ / "seq").string();
  const CliRun truth = RunCli("truth " + seq + " --out " + (dir_ / "truth").string());
  ASSERT_EQ(truth.exit_code, 0) << truth.output;
  Result<Raster> r = io::ReadGeoTiff((dir_ / "truth" / "ground_truth.tif").string());
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->layers,
            (std::vector<Layer>{Layer::kElevation, Layer::kTraversability, Layer::kState}));
  const nlohmann::json t = Json(dir_ / "truth" / "truth.json");
  EXPECT_EQ(t["scans"], 3);
  EXPECT_EQ(t["points_input"], 3 * 6400);
  EXPECT_GT(t["judged_cells"].get<int>(), 1000);
  EXPECT_EQ(t["non_traversable_cells"], 0);  // flat ground

  ASSERT_EQ(RunCli("thin " + seq + " --keep-every 4 --out " + (dir_ / "thin").string()).exit_code,
            0);
  const CliRun eval =
      RunCli("eval " + (dir_ / "thin").string() + " --truth " +
             (dir_ / "truth" / "ground_truth.tif").string() +
             " --methods baseline,bgk+ --no-figures --out " + (dir_ / "eval").string());
  ASSERT_EQ(eval.exit_code, 0) << eval.output;
  const nlohmann::json e = Json(dir_ / "eval" / "eval.json");
  ASSERT_EQ(e["methods"].size(), 2u);
  const nlohmann::json& baseline = e["methods"][0]["offline"];
  const nlohmann::json& bgk = e["methods"][1]["offline"];
  EXPECT_EQ(baseline["truth_cells"], t["judged_cells"]);
  // A quarter of the points observes fewer cells than all of them; BGK fills the gaps.
  EXPECT_LT(baseline["coverage"].get<double>(), 1.0);
  EXPECT_GT(bgk["coverage"].get<double>(), baseline["coverage"].get<double>());
}

}  // namespace
}  // namespace bgkmap::testing
