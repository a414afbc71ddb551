// The RPC layer's request checks without a server: each refusal is INVALID_ARGUMENT (or
// RESOURCE_EXHAUSTED-like limits) naming the field, the value and the limit; a metric box maps
// to the cells it covers, half-open and aligned to the stride; a good scan is prepared exactly as
// the engine prepares it and keeps its raw points when asked.
#include "rpc/request_checks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "bgkmap/proto/scan_codec.h"

namespace bgkmap {
namespace {

v1::BoundingBox Box(double min_x, double min_y, double max_x, double max_y) {
  v1::BoundingBox b;
  b.set_min_x(min_x);
  b.set_min_y(min_y);
  b.set_max_x(max_x);
  b.set_max_y(max_y);
  return b;
}

v1::Scan GroundScan(const std::string& robot, int n) {
  v1::Scan scan;
  scan.set_robot_id(robot);
  scan.set_sequence(1);
  std::vector<Point3f> points;
  for (int i = 0; i < n; ++i) points.push_back({2.0f + 0.05f * i, 0.5f * (i % 7), -1.0f});
  scan.set_points(
      std::string(reinterpret_cast<const char*>(points.data()), points.size() * sizeof(Point3f)));
  scan.mutable_pose()->mutable_rotation()->set_w(1.0);
  scan.mutable_pose()->mutable_translation()->set_x(1.0);
  scan.mutable_stamp()->set_seconds(12);
  scan.mutable_stamp()->set_nanos(345);
  return scan;
}

// `message` starts with `prefix`.
::testing::AssertionResult StartsWith(const grpc::Status& s, const std::string& prefix) {
  if (s.error_message().rfind(prefix, 0) == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "'" << s.error_message() << "' does not start with '" << prefix << "'";
}

TEST(RequestChecksTest, RobotIdsArePrintableAndAtMost128Bytes) {
  EXPECT_TRUE(CheckRobotId("r1").ok());
  EXPECT_TRUE(CheckRobotId(std::string(128, 'a')).ok());
  EXPECT_TRUE(CheckRobotId("ünïcode").ok());  // bytes >= 0x80 are text
  EXPECT_EQ(CheckRobotId("").error_message(), "robot_id: must not be empty");
  EXPECT_EQ(CheckRobotId(std::string(129, 'a')).error_message(),
            "robot_id: 129 bytes exceed the limit of 128");
  const grpc::Status newline = CheckRobotId("r\n1");
  EXPECT_EQ(newline.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(newline.error_message(),
            "robot_id: byte 1 is the control character 0x0a; robot ids must be printable text");
  EXPECT_FALSE(CheckRobotId(std::string("a\x7f", 2)).ok());
}

TEST(RequestChecksTest, CoordinatesAreFiniteAndWithinTheLimit) {
  ServerLimits limits;
  limits.max_coordinate = 100;
  EXPECT_TRUE(CheckCoordinate(-100, "x", limits).ok());
  EXPECT_EQ(CheckCoordinate(std::nan(""), "poses[2].x", limits).error_message(),
            "poses[2].x: nan is not finite");
  EXPECT_EQ(CheckCoordinate(100.5, "x", limits).error_message(),
            "x: |100.5| exceeds server.max_coordinate = 100 m");
}

TEST(RequestChecksTest, PosesAreUnitQuaternionsWithinTheTolerance) {
  const MapParams params;
  const ServerLimits limits;
  v1::Pose3 pose;
  pose.mutable_rotation()->set_w(2.0);  // normalised only within the tolerance
  Pose out;
  EXPECT_TRUE(StartsWith(CheckPose(pose, params, limits, &out),
                         "pose.rotation: quaternion norm 2 is not 1 within "
                         "server.quaternion_tolerance = 0.001"));
  pose.mutable_rotation()->set_w(1.0005);
  pose.mutable_translation()->set_z(3.0);
  ASSERT_TRUE(CheckPose(pose, params, limits, &out).ok());
  EXPECT_DOUBLE_EQ(out.rotation(0, 0), 1.0);  // normalised
  EXPECT_DOUBLE_EQ(out.translation.z(), 3.0);
  pose.mutable_rotation()->set_x(std::numeric_limits<double>::infinity());
  EXPECT_EQ(CheckPose(pose, params, limits, &out).error_message(),
            "pose.rotation.x: inf is not finite");
  pose.mutable_rotation()->set_x(0);
  pose.mutable_translation()->set_y(2e6);
  EXPECT_EQ(CheckPose(pose, params, limits, &out).error_message(),
            "pose.translation.y: |2e+06| exceeds server.max_coordinate = 1e+06 m");
}

TEST(RequestChecksTest, AScanIsPreparedAsTheEngineDoesAndKeepsItsRawPoints) {
  const MapParams params;
  const ServerLimits limits;
  const v1::Scan scan = GroundScan("r1", 200);
  PreparedScan prepared;
  std::shared_ptr<RawScan> raw;
  ASSERT_TRUE(PrepareScanMessage(scan, params, limits, &prepared, &raw).ok());
  ASSERT_NE(raw, nullptr);
  EXPECT_EQ(raw->points.size(), 200u);
  EXPECT_EQ(std::memcmp(raw->points.data(), scan.points().data(), scan.points().size()), 0);
  EXPECT_DOUBLE_EQ(raw->pose.translation.x(), 1.0);
  Result<PreparedScan> engine = PrepareScan(params, raw->points, raw->pose);
  ASSERT_TRUE(engine.ok());
  ASSERT_EQ(prepared.cells.size(), engine->cells.size());
  for (size_t i = 0; i < prepared.cells.size(); ++i) {
    EXPECT_EQ(prepared.cells[i].cell, engine->cells[i].cell);
    EXPECT_EQ(prepared.cells[i].y, engine->cells[i].y);  // bitwise
  }
  EXPECT_EQ(prepared.counts.kept, engine->counts.kept);
  EXPECT_EQ(prepared.stamp_ns, 12'000'000'345);
  // Without a place for it, no raw scan is kept.
  PreparedScan again;
  EXPECT_TRUE(PrepareScanMessage(scan, params, limits, &again).ok());
}

TEST(RequestChecksTest, AMalformedScanIsRefusedNamingTheField) {
  const MapParams params;
  ServerLimits limits;
  PreparedScan out;
  v1::Scan torn = GroundScan("r1", 10);
  torn.mutable_points()->pop_back();
  EXPECT_EQ(PrepareScanMessage(torn, params, limits, &out).error_message(),
            "points: 119 bytes is not a multiple of 12 (packed little-endian float32 x, y, z)");
  limits.max_points_per_scan = 5;
  EXPECT_EQ(PrepareScanMessage(GroundScan("r1", 10), params, limits, &out).error_message(),
            "points: 10 points exceed server.max_points_per_scan = 5");
  v1::Scan no_pose = GroundScan("r1", 2);
  no_pose.clear_pose();
  EXPECT_EQ(PrepareScanMessage(no_pose, params, ServerLimits{}, &out).error_message(),
            "pose: missing");
  EXPECT_EQ(PrepareScanMessage(GroundScan("", 2), params, ServerLimits{}, &out).error_message(),
            "robot_id: must not be empty");
  // An absurd stamp does not overflow: the scan is unstamped.
  v1::Scan far = GroundScan("r1", 2);
  far.mutable_stamp()->set_seconds(std::numeric_limits<int64_t>::max());
  ASSERT_TRUE(PrepareScanMessage(far, params, ServerLimits{}, &out).ok());
  EXPECT_EQ(out.stamp_ns, 0);
}

// The scan's points in the compact encoding, quantized to `step`.
v1::Scan Compact(v1::Scan scan, double step, PointOrder order) {
  std::vector<Point3f> points(scan.points().size() / sizeof(Point3f));
  std::memcpy(points.data(), scan.points().data(), scan.points().size());
  scan.clear_points();
  ToProto(*EncodeCompactPoints(points, step, nullptr, order), scan.mutable_compact_points());
  return scan;
}

// The rule of docs/server.md "Compact scans": a compact scan is prepared from exactly its
// dequantized points, in the order they decode, and those are what is retained.
TEST(RequestChecksTest, ACompactScanIsPreparedFromItsDequantizedPoints) {
  const MapParams params;
  const ServerLimits limits;
  for (PointOrder order : {PointOrder::kScanOrder, PointOrder::kSpatialSort}) {
    const v1::Scan scan = Compact(GroundScan("r1", 300), 0.004, order);
    PreparedScan prepared;
    std::shared_ptr<RawScan> raw;
    ASSERT_TRUE(PrepareScanMessage(scan, params, limits, &prepared, &raw).ok());
    Result<std::vector<Point3f>> decoded =
        DecodeCompactPoints(FromProto(scan.compact_points()), 300);
    ASSERT_TRUE(decoded.ok());
    ASSERT_EQ(raw->points.size(), 300u);
    EXPECT_EQ(std::memcmp(raw->points.data(), decoded->data(), 300 * sizeof(Point3f)), 0);
    Result<PreparedScan> engine = PrepareScan(params, *decoded, raw->pose);
    ASSERT_TRUE(engine.ok());
    EXPECT_EQ(prepared.counts.input, 300u);
    ASSERT_EQ(prepared.cells.size(), engine->cells.size());
    for (size_t i = 0; i < prepared.cells.size(); ++i) {
      EXPECT_EQ(prepared.cells[i].cell, engine->cells[i].cell);
      EXPECT_EQ(prepared.cells[i].y, engine->cells[i].y);  // bitwise
    }
  }
}

TEST(RequestChecksTest, AMalformedCompactScanIsRefusedNamingTheField) {
  const MapParams params;
  ServerLimits limits;
  PreparedScan out;
  const v1::Scan good = Compact(GroundScan("r1", 10), 0.002, PointOrder::kScanOrder);
  v1::Scan both = good;
  both.set_points(std::string(12, '\0'));
  EXPECT_EQ(PrepareScanMessage(both, params, limits, &out).error_message(),
            "points and compact_points: both set; send the points one way");
  v1::Scan zero = good;
  zero.mutable_compact_points()->set_step(0);
  EXPECT_EQ(PrepareScanMessage(zero, params, limits, &out).error_message(),
            "compact_points.step: 0 m must be finite and in (0, 0.01]");
  v1::Scan nan = good;
  nan.mutable_compact_points()->set_step(std::nan(""));
  EXPECT_EQ(PrepareScanMessage(nan, params, limits, &out).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  v1::Scan truncated = good;
  truncated.mutable_compact_points()->mutable_data()->pop_back();
  EXPECT_TRUE(
      StartsWith(PrepareScanMessage(truncated, params, limits, &out), "compact_points.data: "));
  v1::Scan inflating = good;  // the frame holds 10 points, the count says 2
  inflating.mutable_compact_points()->set_count(2);
  EXPECT_EQ(PrepareScanMessage(inflating, params, limits, &out).error_message(),
            "compact_points.data: inflates to 120 bytes, more than count allows (24)");
  limits.max_points_per_scan = 5;
  EXPECT_EQ(PrepareScanMessage(good, params, limits, &out).error_message(),
            "compact_points.count: 10 points exceed server.max_points_per_scan = 5");
}

TEST(RequestChecksTest, ABoxCoversItsCellsHalfOpenAlignedToTheStride) {
  const GridGeometry g(0.1, 64);
  const ServerLimits limits;
  CellBox cells;
  ASSERT_TRUE(RegionCells(Box(0, 0, 1, 0.5), "box", g, 1, limits, true, &cells).ok());
  EXPECT_EQ(cells, (CellBox{{0, 0}, {9, 4}}));  // a max on a cell border adds no cell
  // Edges within a micro-cell of a border snap to it (200 / 0.1 is not exactly 2000).
  ASSERT_TRUE(RegionCells(Box(-10, 0, 200, 0.1), "box", g, 1, limits, true, &cells).ok());
  EXPECT_EQ(cells, (CellBox{{-100, 0}, {1999, 0}}));
  // Strides align with the global grid, also below zero.
  ASSERT_TRUE(RegionCells(Box(-0.25, 0.05, 0.35, 0.15), "box", g, 4, limits, true, &cells).ok());
  EXPECT_EQ(cells, (CellBox{{-4, 0}, {3, 3}}));
  // A box thinner than a cell still covers one.
  ASSERT_TRUE(RegionCells(Box(0.01, 0.01, 0.02, 0.02), "box", g, 1, limits, true, &cells).ok());
  EXPECT_EQ(cells, (CellBox{{0, 0}, {0, 0}}));
}

TEST(RequestChecksTest, ABadBoxIsRefusedNamingTheFieldAndTheLimit) {
  const GridGeometry g(0.1, 64);
  ServerLimits limits;
  CellBox cells;
  EXPECT_EQ(RegionCells(Box(1, 0, 1, 1), "box", g, 1, limits, true, &cells).error_message(),
            "box: min (1, 0) must be below max (1, 1)");
  EXPECT_EQ(RegionCells(Box(0, std::nan(""), 1, 1), "query.box", g, 1, limits, true, &cells)
                .error_message(),
            "query.box.min_y: nan is not finite");
  limits.max_region_cells = 99;
  const grpc::Status big = RegionCells(Box(0, 0, 1, 1), "box", g, 1, limits, true, &cells);
  EXPECT_EQ(big.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(big.error_message(),
            "box: 10 x 10 = 100 pixels at stride 1 exceed server.max_region_cells = 99");
  EXPECT_TRUE(RegionCells(Box(0, 0, 1, 1), "box", g, 1, limits, false, &cells).ok());
}

}  // namespace
}  // namespace bgkmap
