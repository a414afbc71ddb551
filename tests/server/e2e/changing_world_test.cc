// A map that follows a changing world (issue: dynamics), through the real server: a simulated
// VLP-16 watches a place where a 2 x 2 x 1 m box stands or not. Removed after 10 or 1,000 scans,
// the box's place is ground again within 3 scans; placed after 1,000 scans of bare ground, it is
// non-traversable after 1. With `dynamics: off` (the paper) neither holds: the test shows why
// the default changed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "bgkmap/sim/beam_model.h"
#include "bgkmap/sim/box_world.h"
#include "bgkmap/sim/ray_caster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

constexpr double kSensorHeight = 1.5;  // above ground: the box's top (1 m) is in view
const sim::Box kBox{4.0, -1.0, 6.0, 1.0, 1.0};

Pose SensorPose() {
  Pose p;
  p.translation = {0.0, 0.0, kSensorHeight};
  return p;
}

// One simulated scan of the world with or without the box (a static robot sees the same scan
// each time; the map must still change its mind within a few of them).
const std::vector<Point3f>& WorldScan(bool with_box) {
  static const std::vector<Point3f> bare =
      sim::SimulateScan(sim::BoxWorld{}, sim::Vlp16(), SensorPose());
  static const std::vector<Point3f> boxed =
      sim::SimulateScan(sim::BoxWorld({kBox}), sim::Vlp16(), SensorPose());
  return with_box ? boxed : bare;
}

class Robot {
 public:
  explicit Robot(Client& client) : client_(client) {}

  // Sends `n` scans of the world, on one stream.
  void Send(int n, bool with_box) {
    std::vector<ScanData> scans(static_cast<size_t>(n));
    for (ScanData& s : scans) {
      s.robot_id = id_;
      s.sequence = ++sequence_;
      s.stamp_ns = static_cast<int64_t>(sequence_) * 100'000'000;  // 10 Hz
      s.pose = ScanPose::FromPose(SensorPose());
      s.points = WorldScan(with_box);
    }
    RpcResult<std::vector<ScanAck>> acks = client_.IngestAll(scans);
    ASSERT_TRUE(acks.ok()) << acks.status().ToString();
    for (const ScanAck& a : *acks) ASSERT_EQ(a.status, AckStatus::kApplied);
  }

 private:
  Client& client_;
  const std::string id_ = "box-watcher";
  uint64_t sequence_ = 0;
};

// The cells of the box's footprint that a scan of the world (with or without the box) observes:
// "the scans that see its place".
std::vector<std::array<double, 2>> SeenCells(bool with_box) {
  const MapParams params;
  const Result<PreparedScan> scan = PrepareScan(params, WorldScan(with_box), SensorPose());
  EXPECT_TRUE(scan.ok());
  std::vector<std::array<double, 2>> xy;
  for (const ObservedCell& oc : scan->cells) {
    const double x = (oc.cell.x + 0.5) * params.resolution;
    const double y = (oc.cell.y + 0.5) * params.resolution;
    if (kBox.Contains(x, y) && (!with_box || oc.y > 0.5)) xy.push_back({x, y});
  }
  return xy;
}

struct Cells {
  int known = 0;
  int ground = 0;           // known, within 0.05 m of the ground and traversable
  int non_traversable = 0;  // known and non-traversable
  int raised = 0;           // known and more than 0.05 m above the ground
  float max_elevation = -INFINITY;
};

Cells Read(Client& client, const std::vector<std::array<double, 2>>& xy) {
  const std::vector<Layer> layers = {Layer::kElevation, Layer::kState};
  RpcResult<PointValues> values = client.QueryPoints(xy, layers);
  EXPECT_TRUE(values.ok()) << values.status().ToString();
  Cells f;
  if (!values.ok()) return f;
  for (size_t i = 0; i < xy.size(); ++i) {
    const float z = values->at(i, 0);
    const auto state = static_cast<CellState>(values->at(i, 1));
    if (state == CellState::kUnknown) continue;
    ++f.known;
    f.max_elevation = std::max(f.max_elevation, z);
    if (state == CellState::kNonTraversable) ++f.non_traversable;
    if (std::abs(z) > 0.05f) ++f.raised;
    if (std::abs(z) <= 0.05f && state == CellState::kTraversable) ++f.ground;
  }
  return f;
}

// Every cell centre of the box's footprint.
std::vector<std::array<double, 2>> FootprintCells() {
  std::vector<std::array<double, 2>> xy;
  for (double y = kBox.ymin + 0.05; y < kBox.ymax; y += 0.1) {
    for (double x = kBox.xmin + 0.05; x < kBox.xmax; x += 0.1) xy.push_back({x, y});
  }
  return xy;
}

ServerConfig ConfigWith(Dynamics dynamics) {
  ServerConfig config = TestConfig();
  config.map.dynamics = dynamics;
  return config;
}

// Scans without the box until its place is ground again: every cell a bare scan sees there is
// ground and traversable, and no known cell of the footprint stands above the ground. Returns
// how many scans it took (or max_scans + 1).
int ScansToClear(Client& client, Robot& robot, int max_scans) {
  const std::vector<std::array<double, 2>> seen = SeenCells(false);
  EXPECT_GT(seen.size(), 20u);
  for (int k = 1; k <= max_scans; ++k) {
    robot.Send(1, false);
    const Cells s = Read(client, seen);
    const Cells all = Read(client, FootprintCells());
    if (s.ground == static_cast<int>(seen.size()) && all.raised == 0) return k;
  }
  return max_scans + 1;
}

class ChangingWorldTest : public ::testing::TestWithParam<int> {};

TEST_P(ChangingWorldTest, RemovedBoxIsGroundWithinThreeScans) {
  ServerFixture fixture(ConfigWith(Dynamics::kOn));
  Robot robot(fixture.client());
  robot.Send(GetParam(), true);
  const Cells with_box = Read(fixture.client(), FootprintCells());
  ASSERT_GT(with_box.known, 50) << "the sensor must see the box";
  EXPECT_GT(with_box.max_elevation, 0.9f);
  EXPECT_GT(with_box.non_traversable, 0);

  const int scans = ScansToClear(fixture.client(), robot, 10);
  std::printf("box seen %d times: its place is ground after %d scans without it\n", GetParam(),
              scans);
  EXPECT_LE(scans, 3);
}

INSTANTIATE_TEST_SUITE_P(History, ChangingWorldTest, ::testing::Values(10, 1000));

TEST(ChangingWorldTest, BoxPlacedAfterLongBareHistoryIsAnObstacleAfterOneScan) {
  ServerFixture fixture(ConfigWith(Dynamics::kOn));
  Robot robot(fixture.client());
  robot.Send(1000, false);
  const std::vector<std::array<double, 2>> on_box = SeenCells(true);
  ASSERT_GT(on_box.size(), 20u);
  const Cells before = Read(fixture.client(), on_box);
  EXPECT_LT(before.max_elevation, 0.05f);
  robot.Send(1, true);
  // Every cell the box scan saw on the box (top or face) stands up and is non-traversable.
  const Cells after = Read(fixture.client(), on_box);
  std::printf(
      "box placed after 1000 bare scans, 1 scan later: %d of %d cells seen on it are "
      "non-traversable, max elevation %.3f m\n",
      after.non_traversable, after.known, after.max_elevation);
  EXPECT_EQ(after.known, static_cast<int>(on_box.size()));
  EXPECT_EQ(after.non_traversable, after.known);
  EXPECT_GT(after.max_elevation, 0.5f);
}

// The paper's pure accumulation, for contrast: the defect the issue measured.
TEST(ChangingWorldTest, WithoutDynamicsTheMapDoesNotFollow) {
  ServerFixture fixture(ConfigWith(Dynamics::kOff));
  Robot robot(fixture.client());
  robot.Send(40, true);
  const int scans = ScansToClear(fixture.client(), robot, 10);
  std::printf("dynamics off: box seen 40 times, place still not ground after %d scans\n", scans);
  EXPECT_GT(scans, 10);
}

}  // namespace
}  // namespace bgkmap::testing

namespace bgkmap::testing {
namespace {

// The robot stands on its footprint: a VLP-16 1.5 m up never sees the ground within ~5.6 m, so a
// path check from the robot's own pose was "unsafe, 100 % unknown". With map.sensor_height set,
// each scan's pose says the ground under the robot is there and traversable.
TEST(ChangingWorldTest, APathFromTheRobotsOwnPoseIsKnownWithItsFootprint) {
  PathQuery here;  // where the robot stands (ahead of it is the lidar's blind disk: unknown)
  here.poses = {{0.0, 0.0, 0.0}};
  here.radius = 0.3;  // the map's robot_radius
  for (double sensor_height : {0.0, kSensorHeight}) {
    ServerConfig config = TestConfig();
    config.map.sensor_height = sensor_height;
    ServerFixture server(config);
    Robot robot(server.client());
    robot.Send(1, false);
    RpcResult<PathCheck> check = server.client().CheckPath(here);
    ASSERT_TRUE(check.ok()) << check.status().ToString();
    ASSERT_EQ(check->poses.size(), 1u);
    if (sensor_height == 0.0) {
      EXPECT_FALSE(check->safe);
      EXPECT_EQ(check->poses[0].unknown_fraction, 1.0f);
    } else {
      EXPECT_TRUE(check->safe);
      EXPECT_EQ(check->poses[0].unknown_fraction, 0.0f);
    }
  }
}

}  // namespace
}  // namespace bgkmap::testing
