// OctoMap scan graphs through OpenScanSource: a graph written by octomap's own API reads back as
// one posed scan per node; truncated or corrupt files are one clear error line, and octomap is
// never handed a file that does not match its layout.
#include <gtest/gtest.h>
#include <octomap/ScanGraph.h>
#include <unistd.h>

#include <Eigen/LU>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>

#include "scan_source.h"

namespace bgkmap::cli {
namespace {

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("bgkmap_graph_" + std::to_string(getpid()) + "_" + name))
      .string();
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// Three scans of 2, 3 and 0 points; node k at (k, 2k, 1) turned by k * 30 deg about z.
std::string WriteGraph(const std::string& name) {
  octomap::ScanGraph graph;
  for (int k = 0; k < 3; ++k) {
    auto* cloud = new octomap::Pointcloud();  // the graph owns it
    for (int i = 0; i < 2 + k && k < 2; ++i) cloud->push_back(1.0f + i, 0.5f * k, -1.0f);
    const double yaw = k * std::numbers::pi / 6;
    graph.addNode(cloud, octomap::pose6d(k, 2 * k, 1, 0, 0, yaw));
  }
  graph.addEdge(0, 1);
  graph.addEdge(1, 2);
  const std::string path = TempPath(name);
  EXPECT_TRUE(graph.writeBinary(path));
  return path;
}

// The error of opening `path`, checking it is one line and that nothing reached stderr.
std::string OpenError(const std::string& path) {
  ::testing::internal::CaptureStderr();
  Result<std::unique_ptr<ScanSource>> s = OpenScanSource(path);
  const std::string printed = ::testing::internal::GetCapturedStderr();
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(printed, "");
  if (s.ok()) return "";
  EXPECT_EQ(s.status().message().find('\n'), std::string::npos);
  return s.status().message();
}

TEST(ScanGraphSourceTest, OneScanPerNodeInTheSensorFrameWithItsPose) {
  const std::string path = WriteGraph("ok.graph");
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(path);
  ASSERT_TRUE(source.ok()) << source.status().message();
  ASSERT_EQ((*source)->size(), 3u);
  EXPECT_NE((*source)->Describe().find("3 scans"), std::string::npos);
  for (size_t k = 0; k < 3; ++k) {
    Result<SourceScan> scan = (*source)->Read(k);
    ASSERT_TRUE(scan.ok());
    EXPECT_FALSE(scan->frame_is_map);
    ASSERT_EQ(scan->points.size(), k < 2 ? 2 + k : 0u);
    if (k < 2) {
      EXPECT_FLOAT_EQ(scan->points.back().x, 1.0f + (1 + k));
      EXPECT_FLOAT_EQ(scan->points.back().y, 0.5f * k);
      EXPECT_FLOAT_EQ(scan->points.back().z, -1.0f);
    }
    EXPECT_NEAR(scan->pose.translation.x(), k, 1e-6);
    EXPECT_NEAR(scan->pose.translation.y(), 2.0 * k, 1e-6);
    EXPECT_NEAR(scan->pose.translation.z(), 1.0, 1e-6);
    const double yaw = std::atan2(scan->pose.rotation(1, 0), scan->pose.rotation(0, 0));
    EXPECT_NEAR(yaw, k * std::numbers::pi / 6, 1e-6);
    EXPECT_NEAR(scan->pose.rotation.determinant(), 1.0, 1e-6);
  }
  std::filesystem::remove(path);
}

TEST(ScanGraphSourceTest, TruncatedFilesAreOneClearError) {
  const std::string good = ReadBytes(WriteGraph("src.graph"));
  const std::string path = TempPath("cut.graph");
  for (size_t keep : {size_t{0}, size_t{3}, size_t{10}, good.size() / 2, good.size() - 1}) {
    WriteBytes(path, good.substr(0, keep));
    const std::string msg = OpenError(path);
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find("truncated"), std::string::npos) << keep << ": " << msg;
  }
  std::filesystem::remove(path);
  std::filesystem::remove(TempPath("src.graph"));
}

TEST(ScanGraphSourceTest, CorruptCountsAndGarbageAreOneClearError) {
  const std::string good = ReadBytes(WriteGraph("src2.graph"));
  const std::string path = TempPath("bad.graph");
  std::string huge = good;
  huge[4] = huge[5] = huge[6] = huge[7] = '\x7f';  // first node claims ~2^31 points
  WriteBytes(path, huge);
  EXPECT_NE(OpenError(path).find("a node's point count at byte 4 counts"), std::string::npos);

  std::string tag = good;
  tag[8] = 9;  // the first point claims 9 coordinates
  WriteBytes(path, tag);
  EXPECT_NE(OpenError(path).find("has 9 values, expected 3"), std::string::npos);

  std::string edge = good;
  edge[good.size() - 160] = 99;  // the first of the two 80-byte edges starts from node id 99
  WriteBytes(path, edge);
  EXPECT_NE(OpenError(path).find("edge 0 joins unknown node ids 99 and 1"), std::string::npos);

  WriteBytes(path, good + "xyz");
  EXPECT_NE(OpenError(path).find("3 bytes after the last edge"), std::string::npos);

  std::string text = "# not a graph\n";
  text.resize(200, 'a');
  WriteBytes(path, text);
  EXPECT_NE(OpenError(path).find("not an OctoMap scan graph"), std::string::npos);
  std::filesystem::remove(path);
  std::filesystem::remove(TempPath("src2.graph"));
}

}  // namespace
}  // namespace bgkmap::cli
