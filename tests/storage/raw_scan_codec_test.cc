// A retained scan (storage/raw_scan_codec.h): a scan that came compact is stored compactly and
// gives back exactly its points, in their order, with its quantum (both orders of the encoding,
// on a real Ouster scan), in at most a quarter of the float32 format's bytes; anything else is
// stored as float32; damage is DataLoss.
#include "bgkmap/storage/raw_scan_codec.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "bgkmap/proto/compact_points.h"

namespace bgkmap::storage {
namespace {

std::vector<Point3f> OusterScan() {
  std::ifstream in(std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street/velodyne/000001.bin",
                   std::ios::binary);
  std::vector<Point3f> points;
  float xyzi[4];
  while (in.read(reinterpret_cast<char*>(xyzi), sizeof xyzi)) {
    points.push_back({xyzi[0], xyzi[1], xyzi[2]});
  }
  return points;
}

RawScan Sent(std::vector<Point3f> points, double quantum) {
  RawScan s;
  s.pose = Pose::FromQuaternion(0.99, 0.0, 0.1, 0.0995, 10.5, -3.25, 1.75);
  s.points = std::move(points);
  s.quantum = quantum;
  return s;
}

void ExpectSame(const RawScan& a, const RawScan& b) {
  EXPECT_EQ(a.pose.rotation, b.pose.rotation);
  EXPECT_EQ(a.pose.translation, b.pose.translation);
  EXPECT_EQ(a.frame_is_map, b.frame_is_map);
  EXPECT_EQ(a.quantum, b.quantum);
  ASSERT_EQ(a.points.size(), b.points.size());
  EXPECT_EQ(std::memcmp(a.points.data(), b.points.data(), a.points.size() * sizeof(Point3f)), 0);
}

TEST(RawScanCodecTest, ACompactScanIsStoredCompactlyAndComesBackExactly) {
  const std::vector<Point3f> scan = OusterScan();
  ASSERT_GT(scan.size(), 100000u) << "needs ../shared/data/ouster_os1_128_street";
  const size_t float_bytes = EncodeRawScan(Sent(scan, 0.0)).size();
  for (PointOrder order : {PointOrder::kScanOrder, PointOrder::kSpatialSort}) {
    // The points as the server has them after decoding the robot's compact scan.
    Result<CompactPoints> wire = EncodeCompactPoints(scan, 0.002, nullptr, order);
    ASSERT_TRUE(wire.ok());
    Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*wire, scan.size());
    ASSERT_TRUE(decoded.ok());
    const RawScan sent = Sent(*decoded, 0.002);
    const std::string stored = EncodeRawScan(sent);
    EXPECT_LE(stored.size() * 4, float_bytes) << static_cast<int>(order);
    Result<RawScan> back = DecodeRawScan(stored);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ExpectSame(*back, sent);
  }
}

TEST(RawScanCodecTest, PointsOffTheGridAndFloatScansAreStoredAsFloat32) {
  std::vector<Point3f> points = {{1.0001f, 2.0f, -1.5f}, {3.25f, 0.5f, 0.125f}};
  for (double quantum : {0.0, 0.002}) {  // 1.0001 is not a multiple of 2 mm
    const RawScan sent = Sent(points, quantum);
    const std::string stored = EncodeRawScan(sent);
    EXPECT_EQ(stored[0], 1);  // format 1
    Result<RawScan> back = DecodeRawScan(stored);
    ASSERT_TRUE(back.ok());
    EXPECT_EQ(back->quantum, 0.0);
    EXPECT_EQ(std::memcmp(back->points.data(), points.data(), 2 * sizeof(Point3f)), 0);
  }
  const RawScan empty = Sent({}, 0.002);
  Result<RawScan> none = DecodeRawScan(EncodeRawScan(empty));
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->points.empty());
}

TEST(RawScanCodecTest, DamageIsDataLoss) {
  Result<CompactPoints> wire = EncodeCompactPoints(OusterScan(), 0.002);
  ASSERT_TRUE(wire.ok());
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*wire, wire->count);
  ASSERT_TRUE(decoded.ok());
  std::string stored = EncodeRawScan(Sent(*decoded, 0.002));
  ASSERT_EQ(stored[0], 2);
  stored[stored.size() / 2] ^= 0x10;
  Result<RawScan> back = DecodeRawScan(stored);
  ASSERT_FALSE(back.ok());
  EXPECT_EQ(back.status().code(), Status::Code::kDataLoss);
}

}  // namespace
}  // namespace bgkmap::storage
