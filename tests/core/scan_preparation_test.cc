#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bgkmap/core/scan.h"

namespace bgkmap {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(ScanPreparationTest, BinsPointsIntoCellsWithMaxOrMean) {
  MapParams p;
  p.min_range = 0.0;
  const std::vector<Point3f> pts = {
      {0.51f, 0.52f, -1.0f}, {0.55f, 0.58f, -0.5f}, {-0.05f, 0.0f, -2.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s->cells.size(), 2u);
  // Sorted by (x, y): cell (-1, 0) first, then (5, 5).
  EXPECT_EQ(s->cells[0].cell, (CellIndex{-1, 0}));
  EXPECT_EQ(s->cells[1].cell, (CellIndex{5, 5}));
  EXPECT_DOUBLE_EQ(s->cells[1].y, -0.5);
  p.observation = Observation::kMean;
  s = PrepareScan(p, pts, Pose{});
  EXPECT_DOUBLE_EQ(s->cells[1].y, -0.75);
}

TEST(ScanPreparationTest, TransformsByThePose) {
  MapParams p;
  p.min_range = 0.0;
  Pose pose = Pose::FromQuaternion(std::cos(M_PI / 4), 0, 0, std::sin(M_PI / 4), 10, 20, 2);
  const std::vector<Point3f> pts = {{1.05f, 0.03f, -2.0f}};  // 90 deg yaw: (x, y) -> (-y, x)
  Result<PreparedScan> s = PrepareScan(p, pts, pose);
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s->cells.size(), 1u);
  EXPECT_EQ(s->cells[0].cell, (CellIndex{99, 210}));  // map point (9.97, 21.05)
  EXPECT_NEAR(s->cells[0].y, 0.0, 1e-6);
}

TEST(ScanPreparationTest, DropsAndCountsEveryKindOfBadPoint) {
  MapParams p;  // min_range 1, max_range 100, max_height_above_sensor 0.5
  const std::vector<Point3f> pts = {
      {5, 0, -1},                                     // kept
      {kNaN, 0, 0},     {0, kInf, 0}, {0, 0, -kInf},  // non-finite
      {0.2f, 0, -0.1f},                               // too close
      {200, 0, -1},                                   // too far
      {5, 0, 3},                                      // above the sensor: overhang
  };
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.input, 7u);
  EXPECT_EQ(s->counts.kept, 1u);
  EXPECT_EQ(s->counts.dropped_nonfinite, 3u);
  EXPECT_EQ(s->counts.dropped_range, 2u);
  EXPECT_EQ(s->counts.dropped_height, 1u);
  EXPECT_EQ(s->cells.size(), 1u);
}

TEST(ScanPreparationTest, FrameIsMapSkipsSensorFilters) {
  MapParams p;
  const std::vector<Point3f> pts = {{0.0f, 0.0f, 50.0f}, {500.0f, 0.0f, 0.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{}, /*frame_is_map=*/true);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.kept, 2u);
}

TEST(ScanPreparationTest, PointsBeyondTheCellRangeAreDroppedNotWrapped) {
  MapParams p;
  p.max_range = 1e12;
  const std::vector<Point3f> pts = {{1e9f, 0, -1}, {5, 0, -1}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.dropped_out_of_bounds, 1u);
  EXPECT_EQ(s->counts.kept, 1u);
}

TEST(ScanPreparationTest, RejectsNonRigidAndNonFinitePoses) {
  const MapParams p;
  const std::vector<Point3f> pts = {{5, 0, -1}};
  Pose scaled;
  scaled.rotation *= 1.01;
  Result<PreparedScan> s = PrepareScan(p, pts, scaled);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("orthonormal"), std::string::npos) << s.status().message();

  Pose reflected;
  reflected.rotation(2, 2) = -1;  // orthonormal but det -1
  EXPECT_FALSE(PrepareScan(p, pts, reflected).ok());

  Pose nan_pose;
  nan_pose.translation.x() = std::nan("");
  s = PrepareScan(p, pts, nan_pose);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("finite"), std::string::npos);

  Pose far;
  far.translation.x() = 1e12;
  s = PrepareScan(p, pts, far);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), Status::Code::kOutOfRange);
}

TEST(ScanPreparationTest, FootprintCoversKernelSupportAcrossTileBorders) {
  MapParams p;  // l = 0.3 (2 cells reach), tile 64
  p.min_range = 0;
  // One point in cell (63, 0): the kernel reaches cells 61..65, so tiles (0,-1), (0,0), (1,-1),
  // (1,0) are candidates; the corner ones are beyond reach? (64, -1) is at offset (1, -1): yes.
  const std::vector<Point3f> pts = {{6.35f, 0.05f, -1.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  const std::vector<TileKey> expected = {{0, -1}, {0, 0}, {1, -1}, {1, 0}};
  EXPECT_EQ(s->write_tiles, expected);
  // Far from borders: a single tile.
  s = PrepareScan(p, std::vector<Point3f>{{3.25f, 3.25f, -1.0f}}, Pose{});
  EXPECT_EQ(s->write_tiles, (std::vector<TileKey>{{0, 0}}));
}

}  // namespace
}  // namespace bgkmap
