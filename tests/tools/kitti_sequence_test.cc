#include "bgkmap/io/kitti_sequence.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "test_files.h"

namespace bgkmap::io {
namespace {

namespace fs = std::filesystem;
using testing::ReadBytes;
using testing::TempDir;
using testing::WriteBytes;

const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

// A copy of the street sequence with its poses.txt replaced by `poses`.
void CopyStreetWithPoses(const TempDir& dir, const std::string& poses) {
  fs::create_directories(dir.path() / "velodyne");
  for (int k = 0; k < 3; ++k) {
    fs::copy_file(kStreet + "/velodyne/" + KittiScanFileName(k),
                  dir.path() / "velodyne" / KittiScanFileName(k));
  }
  WriteBytes(dir.Path("poses.txt"), poses);
}

std::string StreetPoseLines(int n) {
  const std::string all = ReadBytes(kStreet + "/poses.txt");
  size_t end = 0;
  for (int i = 0; i < n; ++i) end = all.find('\n', end) + 1;
  return all.substr(0, end);
}

TEST(KittiSequenceTest, ReadsRealOusterScans) {
  Result<KittiSequence> seq = KittiSequence::Open(kStreet);
  ASSERT_TRUE(seq.ok()) << seq.status().message();
  ASSERT_EQ(seq->size(), 3u);
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<Scan> scan = seq->Read(k);
    ASSERT_TRUE(scan.ok()) << scan.status().message();
    EXPECT_EQ(scan->points.size() * 16, fs::file_size(seq->scan_path(k)));
    EXPECT_GT(scan->points.size(), 100'000u);
    EXPECT_LT(scan->points.size(), 115'000u);
    std::vector<float> z;
    for (const Point3f& p : scan->points) {
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
      z.push_back(p.z);
    }
    // The ground is about 2 m below the sensor: the low decile of z must sit near -2 m.
    std::nth_element(z.begin(), z.begin() + z.size() / 10, z.end());
    EXPECT_NEAR(z[z.size() / 10], -2.0, 0.7);
    const Eigen::Matrix3d& r = scan->pose.rotation;
    EXPECT_TRUE((r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), 1e-6));
  }
  EXPECT_TRUE(seq->pose(0).rotation.isIdentity(0));
  EXPECT_TRUE(seq->pose(0).translation.isZero(0));
  EXPECT_NEAR(seq->pose(1).translation.x(), 0.2454105091588855, 1e-15);
  EXPECT_NEAR(seq->pose(1).rotation(0, 1), -1.492127441878369988e-04, 1e-18);
  EXPECT_NEAR(seq->pose(2).translation.x(), 0.4978255321866780, 1e-15);
}

TEST(KittiSequenceTest, WriterRoundTripsExactly) {
  TempDir dir;
  fs::create_directories(dir.path() / "velodyne");
  std::vector<std::vector<Point3f>> scans = {
      {{1.5f, -2.25f, 0.125f}, {1e-7f, 3e4f, -0.0f}},
      {},
      {{-4.0f, 5.0f, 6.0f}},
  };
  Pose moved;
  moved.rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, 0.2, 0.9).normalized()).matrix();
  moved.translation = {1.0 / 3.0, -2e5, 1e-9};
  for (size_t k = 0; k < scans.size(); ++k) {
    const std::vector<float> intensity(scans[k].size(), 7.0f);
    ASSERT_TRUE(
        WriteKittiScan(dir.Path("velodyne/" + KittiScanFileName(k)), scans[k], intensity).ok());
    ASSERT_TRUE(AppendPose(dir.Path("poses.txt"), k == 1 ? moved : Pose{}).ok());
  }
  Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
  ASSERT_TRUE(seq.ok()) << seq.status().message();
  ASSERT_EQ(seq->size(), 3u);
  for (size_t k = 0; k < scans.size(); ++k) {
    Result<Scan> scan = seq->Read(k);
    ASSERT_TRUE(scan.ok()) << scan.status().message();
    ASSERT_EQ(scan->points.size(), scans[k].size());
    for (size_t i = 0; i < scans[k].size(); ++i) {
      EXPECT_EQ(scan->points[i].x, scans[k][i].x);
      EXPECT_EQ(scan->points[i].y, scans[k][i].y);
      EXPECT_EQ(scan->points[i].z, scans[k][i].z);
    }
  }
  EXPECT_EQ(seq->pose(1).rotation, moved.rotation);  // %.17g round-trips every double
  EXPECT_EQ(seq->pose(1).translation, moved.translation);
  // The intensity column is really written.
  const std::string bytes = ReadBytes(dir.Path("velodyne/000000.bin"));
  float intensity = 0;
  std::memcpy(&intensity, bytes.data() + 12, 4);
  EXPECT_EQ(intensity, 7.0f);
}

TEST(KittiSequenceTest, WriterRejectsMismatchedIntensities) {
  TempDir dir;
  const std::vector<Point3f> points(2, Point3f{0, 0, 0});
  const std::vector<float> intensity(3, 0.0f);
  EXPECT_FALSE(WriteKittiScan(dir.Path("x.bin"), points, intensity).ok());
}

TEST(KittiSequenceTest, MissingDirectoryIsAnError) {
  Result<KittiSequence> seq = KittiSequence::Open("/nonexistent/bgkmap/sequence");
  ASSERT_FALSE(seq.ok());
  EXPECT_NE(seq.status().message().find("/nonexistent/bgkmap/sequence"), std::string::npos);
}

TEST(KittiSequenceTest, FewerPosesThanScansIsAnError) {
  TempDir dir;
  CopyStreetWithPoses(dir, StreetPoseLines(2));
  Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
  ASSERT_FALSE(seq.ok());
  EXPECT_NE(seq.status().message().find("poses.txt: 2 poses for 3 scans"), std::string::npos)
      << seq.status().message();
}

TEST(KittiSequenceTest, BadPoseLinesAreErrorsNamingTheLine) {
  const std::string good = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {good + "1 0 0 0 0 1 0 0 0 0 1\n" + good, "poses.txt:2: expected 12 numbers, found 11"},
      {good + good + "1 0 0 0 0 1 0 0 0 0 1 0 5\n", "poses.txt:3: expected 12 numbers, found 13"},
      {good + "1 0 0 nan 0 1 0 0 0 0 1 0\n" + good, "poses.txt:2: non-finite"},
      {good + "1 0 0 inf 0 1 0 0 0 0 1 0\n" + good, "poses.txt:2: non-finite"},
      {good + "1 0 0 x0 0 1 0 0 0 0 1 0\n" + good, "poses.txt:2: not a number: 'x0'"},
      {good + "1,0 0 0 0 1 0 0 0 0 1 0\n" + good, "poses.txt:2: not a number: '1,0'"},
      {good + "\n" + good + good, "poses.txt:2: empty line"},
  };
  for (const auto& [poses, expected] : cases) {
    TempDir dir;
    CopyStreetWithPoses(dir, poses);
    Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
    ASSERT_FALSE(seq.ok()) << poses;
    EXPECT_NE(seq.status().message().find(expected), std::string::npos)
        << seq.status().message() << " does not contain " << expected;
  }
}

TEST(KittiSequenceTest, TrailingBlankLinesAndExtraPosesAreAccepted) {
  TempDir dir;
  CopyStreetWithPoses(dir, StreetPoseLines(3) + "1 0 0 0 0 1 0 0 0 0 1 0\n\n\n");
  Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
  ASSERT_TRUE(seq.ok()) << seq.status().message();
  EXPECT_EQ(seq->size(), 3u);
}

// KITTI odometry's times.txt: scan k's time on line k, the map time forgetting ages by.
TEST(KittiSequenceTest, TimesAreReadWhenPresent) {
  {
    TempDir dir;
    CopyStreetWithPoses(dir, StreetPoseLines(3));
    Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
    ASSERT_TRUE(seq.ok()) << seq.status().message();
    EXPECT_FALSE(seq->has_times());
    EXPECT_TRUE(std::isnan(seq->Read(1)->time_s));
  }
  {
    TempDir dir;
    CopyStreetWithPoses(dir, StreetPoseLines(3));
    WriteBytes(dir.Path("times.txt"), "0.000000e+00\n1.036190e-01 \n2.07e-01\n3.1\n");
    Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
    ASSERT_TRUE(seq.ok()) << seq.status().message();
    EXPECT_TRUE(seq->has_times());
    EXPECT_EQ(seq->Read(0)->time_s, 0.0);
    EXPECT_EQ(seq->Read(1)->time_s, 1.036190e-01);
    EXPECT_EQ(seq->Read(2)->time_s, 2.07e-01);
  }
  for (const auto& [times, expected] : std::vector<std::pair<std::string, std::string>>{
           {"0\n0.1\n", "times.txt: 2 times for 3 scans"},
           {"0\nx\n0.2\n", "times.txt:2: not a finite number of seconds: 'x'"},
           {"0\n0.1\nnan\n", "times.txt:3: not a finite number of seconds: 'nan'"}}) {
    TempDir dir;
    CopyStreetWithPoses(dir, StreetPoseLines(3));
    WriteBytes(dir.Path("times.txt"), times);
    Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
    ASSERT_FALSE(seq.ok()) << times;
    EXPECT_NE(seq.status().message().find(expected), std::string::npos)
        << seq.status().message() << " does not contain " << expected;
  }
}

TEST(KittiSequenceTest, GapInScanNumberingIsAnError) {
  TempDir dir;
  CopyStreetWithPoses(dir, StreetPoseLines(3));
  fs::remove(dir.path() / "velodyne" / "000001.bin");
  Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
  ASSERT_FALSE(seq.ok());
  EXPECT_NE(seq.status().message().find("scan 000001.bin is missing"), std::string::npos)
      << seq.status().message();
}

TEST(KittiSequenceTest, TruncatedScanIsAnErrorNamingTheFile) {
  TempDir dir;
  CopyStreetWithPoses(dir, StreetPoseLines(3));
  const std::string path = dir.Path("velodyne/000002.bin");
  fs::resize_file(path, fs::file_size(path) - 3);
  Result<KittiSequence> seq = KittiSequence::Open(dir.path().string());
  ASSERT_TRUE(seq.ok()) << seq.status().message();
  EXPECT_TRUE(seq->Read(1).ok());
  Result<Scan> scan = seq->Read(2);
  ASSERT_FALSE(scan.ok());
  EXPECT_EQ(scan.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(scan.status().message().find("000002.bin"), std::string::npos);
  EXPECT_NE(scan.status().message().find("not a multiple of 16"), std::string::npos);
  EXPECT_EQ(seq->Read(3).status().code(), Status::Code::kOutOfRange);
}

TEST(KittiSequenceTest, ScanFileNames) {
  EXPECT_EQ(KittiScanFileName(0), "000000.bin");
  EXPECT_EQ(KittiScanFileName(42), "000042.bin");
  EXPECT_EQ(KittiScanFileName(1234567), "1234567.bin");
}

}  // namespace
}  // namespace bgkmap::io

namespace bgkmap::io {
namespace {

// A folder of PCD scans with poses.txt reads like the .bin folder: the street scans written as
// binary PCD (x y z float32) give the same points bit for bit and the same poses.
TEST(KittiSequenceTest, PcdFolderReadsLikeBinFolder) {
  Result<KittiSequence> bins = KittiSequence::Open(kStreet);
  ASSERT_TRUE(bins.ok());
  TempDir dir;
  fs::create_directories(dir.path() / "velodyne");
  for (size_t k = 0; k < bins->size(); ++k) {
    Result<Scan> s = bins->Read(k);
    ASSERT_TRUE(s.ok());
    std::string pcd = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " +
                      std::to_string(s->points.size()) + "\nHEIGHT 1\nPOINTS " +
                      std::to_string(s->points.size()) + "\nDATA binary\n";
    pcd.append(reinterpret_cast<const char*>(s->points.data()), s->points.size() * sizeof(Point3f));
    std::string name = KittiScanFileName(k);
    name.replace(name.size() - 4, 4, ".pcd");
    WriteBytes((dir.path() / "velodyne" / name).string(), pcd);
  }
  fs::copy_file(kStreet + "/poses.txt", dir.path() / "poses.txt");
  Result<KittiSequence> pcds = KittiSequence::Open(dir.path().string());
  ASSERT_TRUE(pcds.ok()) << pcds.status().message();
  ASSERT_EQ(pcds->size(), bins->size());
  for (size_t k = 0; k < bins->size(); ++k) {
    Result<Scan> a = bins->Read(k), b = pcds->Read(k);
    ASSERT_TRUE(a.ok() && b.ok()) << b.status().message();
    ASSERT_EQ(a->points.size(), b->points.size());
    EXPECT_EQ(std::memcmp(a->points.data(), b->points.data(), a->points.size() * sizeof(Point3f)),
              0);
    EXPECT_EQ(a->pose.rotation, b->pose.rotation);
    EXPECT_EQ(a->pose.translation, b->pose.translation);
  }
  // A .bin among the .pcd files is refused, and so is a folder with neither (it used to be read
  // as an empty sequence, "0 scans").
  fs::copy_file(kStreet + "/velodyne/000000.bin", dir.path() / "velodyne" / "000000.bin");
  Result<KittiSequence> mixed = KittiSequence::Open(dir.path().string());
  ASSERT_FALSE(mixed.ok());
  EXPECT_NE(mixed.status().message().find("mixes .bin and .pcd"), std::string::npos);
  TempDir empty;
  fs::create_directories(empty.path() / "velodyne");
  WriteBytes(empty.Path("poses.txt"), "");
  Result<KittiSequence> none = KittiSequence::Open(empty.path().string());
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.status().message().find("neither NNNNNN.bin nor NNNNNN.pcd"), std::string::npos)
      << none.status().message();
  // A folder without velodyne/ at all says what a sequence folder holds.
  TempDir bare;
  Result<KittiSequence> nothing = KittiSequence::Open(bare.path().string());
  ASSERT_FALSE(nothing.ok());
  EXPECT_EQ(nothing.status().message(),
            bare.path().string() +
                ": no scans (a sequence folder holds velodyne/NNNNNN.bin or velodyne/NNNNNN.pcd "
                "and poses.txt; recordings are .mcap, .db3 or .bag)");
}

}  // namespace
}  // namespace bgkmap::io
