#include "bgkmap/io/pcd_reader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "test_files.h"

namespace bgkmap::io {
namespace {

using testing::TempDir;
using testing::WriteBytes;

template <typename T>
void Append(std::string& bytes, T v) {
  bytes.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

TEST(PcdReaderTest, ReadsAsciiWithExtraFields) {
  TempDir dir;
  const std::string path = dir.Path("ascii.pcd");
  WriteBytes(path,
             "# .PCD v0.7 - Point Cloud Data file format\n"
             "VERSION 0.7\n"
             "FIELDS intensity x normal y z rgb\n"
             "SIZE 4 4 4 4 8 4\n"
             "TYPE F F F F F U\n"
             "COUNT 1 1 3 1 1 1\n"
             "WIDTH 3\n"
             "HEIGHT 1\n"
             "VIEWPOINT 10 20 30 1 0 0 0\n"
             "POINTS 3\n"
             "DATA ascii\n"
             "0.5 1.25 0 0 1 -2.5 100.125 4286611584\n"
             "\n"
             "7 -1e3 0 0 1 2e-3 -0.001 0\r\n"
             "1 nan 0 0 1 nan nan 0\n");
  Result<PcdCloud> cloud = ReadPcd(path);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  EXPECT_EQ(cloud->fields, (std::vector<std::string>{"intensity", "x", "normal", "y", "z", "rgb"}));
  EXPECT_EQ(cloud->width, 3u);
  EXPECT_EQ(cloud->height, 1u);
  ASSERT_EQ(cloud->points.size(), 3u);
  // VIEWPOINT is ignored: points come back as stored.
  EXPECT_DOUBLE_EQ(cloud->points[0].x, 1.25);
  EXPECT_DOUBLE_EQ(cloud->points[0].y, -2.5);
  EXPECT_DOUBLE_EQ(cloud->points[0].z, 100.125);
  EXPECT_DOUBLE_EQ(cloud->points[1].x, -1000.0);
  EXPECT_DOUBLE_EQ(cloud->points[1].y, 0.002);
  EXPECT_DOUBLE_EQ(cloud->points[1].z, -0.001);
  EXPECT_TRUE(std::isnan(cloud->points[2].x));  // organised-cloud holes are kept
}

TEST(PcdReaderTest, ReadsBinaryMixedFloatSizes) {
  TempDir dir;
  const std::string path = dir.Path("binary.pcd");
  std::string bytes =
      "VERSION .7\n"
      "FIELDS x y z label _ intensity\n"
      "SIZE 8 4 8 1 1 2\n"
      "TYPE F F F U I U\n"
      "WIDTH 2\n"
      "HEIGHT 2\n"
      "POINTS 4\n"
      "DATA binary\n";
  for (int i = 0; i < 4; ++i) {
    Append<double>(bytes, 500000.125 + i);  // UTM-sized: needs the 8-byte type
    Append<float>(bytes, -0.5f * i);
    Append<double>(bytes, 1e-3 * i);
    Append<uint8_t>(bytes, 0xAB);
    Append<int8_t>(bytes, -1);
    Append<uint16_t>(bytes, 0xFFFF);
  }
  WriteBytes(path, bytes);
  Result<PcdCloud> cloud = ReadPcd(path);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  EXPECT_EQ(cloud->width, 2u);
  EXPECT_EQ(cloud->height, 2u);
  ASSERT_EQ(cloud->points.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(cloud->points[i].x, 500000.125 + i);
    EXPECT_EQ(cloud->points[i].y, -0.5 * i);
    EXPECT_EQ(cloud->points[i].z, 1e-3 * i);
  }

  // The same file missing its last byte.
  WriteBytes(path, bytes.substr(0, bytes.size() - 1));
  Result<PcdCloud> truncated = ReadPcd(path);
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.status().message().find("truncated"), std::string::npos);
}

TEST(PcdReaderTest, PointsDefaultsToWidthTimesHeight) {
  TempDir dir;
  const std::string path = dir.Path("nopoints.pcd");
  WriteBytes(path,
             "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nDATA ascii\n1 2 3\n4 5 6\n");
  Result<PcdCloud> cloud = ReadPcd(path);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  EXPECT_EQ(cloud->points.size(), 2u);
}

// Found with pcd_reader_fuzzer: the ASCII reader reserved POINTS points before reading any, so
// a header promising 10^11 points threw std::length_error (or bad_alloc) out of ReadPcd.
TEST(PcdReaderTest, HugePointCountInAsciiIsTruncationNotAnAllocation) {
  TempDir dir;
  const std::string path = dir.Path("huge.pcd");
  WriteBytes(path,
             "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 99999999999\nDATA ascii\n"
             "1 2 3\n");
  Result<PcdCloud> cloud = ReadPcd(path);
  ASSERT_FALSE(cloud.ok());
  EXPECT_NE(cloud.status().message().find("truncated: 1 of 99999999999 points present"),
            std::string::npos)
      << cloud.status().message();
}

TEST(PcdReaderTest, ClearErrors) {
  TempDir dir;
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {xyz + "DATA binary_compressed\n\x10\0\0\0", "binary_compressed is unsupported"},
      {xyz + "DATA ascii\n1 2 3\n", "truncated: 1 of 2 points present"},
      {xyz + "DATA ascii\n1 2 3\n4 5\n", "data line 2 has 2 values, expected 3"},
      {xyz + "DATA ascii\n1 2 3\n4 five 6\n", "data line 2: 'five' is not a number"},
      {xyz + "DATA lzf\n", "unknown DATA 'lzf'"},
      {xyz, "no DATA line"},
      {"FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n",
       "no 'z' field"},
      {"FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
       "field 'z' must be TYPE F, SIZE 4 or 8, COUNT 1"},
      {"FIELDS x y z\nSIZE 4 4 4\nTYPE F F I\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
       "field 'z' must be TYPE F"},
      {"FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
       "3 FIELDS but 2 SIZE"},
      {"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH one\nDATA ascii\n", "bad WIDTH line"},
      {"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOLOUR 1\nDATA ascii\n", "unknown header line"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string path = dir.Path("case" + std::to_string(i) + ".pcd");
    WriteBytes(path, cases[i].first);
    Result<PcdCloud> cloud = ReadPcd(path);
    ASSERT_FALSE(cloud.ok()) << cases[i].first;
    const std::string& msg = cloud.status().message();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(cases[i].second), std::string::npos) << msg << " lacks " << cases[i].second;
  }
  EXPECT_EQ(ReadPcd(dir.Path("missing.pcd")).status().code(), Status::Code::kIoError);
}

}  // namespace
}  // namespace bgkmap::io
