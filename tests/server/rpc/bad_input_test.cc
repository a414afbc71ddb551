// Every bad input gets its precise status (naming the field and the limit) and leaves the map
// unchanged: Info and a region query read the same before and after.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bgkmap/v1/map_service.grpc.pb.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

ServerConfig SmallLimits() {
  ServerConfig c = TestConfig();
  c.limits.max_points_per_scan = 50'000;
  c.limits.max_region_cells = 1'000'000;
  c.limits.max_region_read_cells = 16'000'000;
  c.limits.max_query_points = 1'000;
  return c;
}

class BadInputTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fixture_ = new ServerFixture(SmallLimits());
    scans_ = new std::vector<OwnedScan>(SubScans("robot", 8, 3));
    for (size_t i = 0; i < 2; ++i) {
      RpcResult<ScanAck> a = fixture_->client().Insert((*scans_)[i].Data());
      ASSERT_TRUE(a.ok()) << a.status().ToString();
    }
  }
  static void TearDownTestSuite() {
    delete fixture_;
    delete scans_;
  }

  struct State {
    MapInfo info;
    Raster region;
  };
  State Capture() {
    State s;
    RpcResult<MapInfo> info = fixture_->client().Info();
    EXPECT_TRUE(info.ok());
    s.info = *info;
    RpcResult<Raster> region = fixture_->client().QueryRegion({{-40, -40, 40, 40}, {}, 1});
    EXPECT_TRUE(region.ok()) << region.status().ToString();
    s.region = *region;
    return s;
  }
  void SetUp() override { before_ = Capture(); }
  void ExpectUnchanged() {
    const State after = Capture();
    EXPECT_EQ(after.info.map_version, before_.info.map_version);
    EXPECT_EQ(after.info.known_cells, before_.info.known_cells);
    EXPECT_EQ(after.info.tile_count, before_.info.tile_count);
    EXPECT_EQ(after.info.scans_applied, before_.info.scans_applied);
    EXPECT_TRUE(RastersMatch(after.region, before_.region, 0.0));
  }

  // A valid third scan to corrupt (sequence 100: never applied).
  static OwnedScan Good() {
    OwnedScan s = (*scans_)[2];
    s.sequence = 100;
    return s;
  }

  // Sends `scan` unary and on a stream; both must fail with `code` and mention every `needle`.
  void ExpectRejected(const ScanData& scan, RpcCode code, std::vector<std::string> needles) {
    RpcResult<ScanAck> unary = fixture_->client().Insert(scan);
    ASSERT_FALSE(unary.ok());
    EXPECT_EQ(unary.status().code(), code) << unary.status().ToString();
    for (const std::string& n : needles) {
      EXPECT_NE(unary.status().message().find(n), std::string::npos)
          << "'" << unary.status().message() << "' does not mention '" << n << "'";
    }
    const ScanData list[] = {scan};
    RpcResult<std::vector<ScanAck>> streamed = fixture_->client().IngestAll(list);
    ASSERT_TRUE(streamed.ok()) << streamed.status().ToString();  // the stream survives
    ASSERT_EQ(streamed->size(), 1u);
    EXPECT_EQ((*streamed)[0].status, AckStatus::kRejected);
    EXPECT_EQ((*streamed)[0].error.code(), code);
    EXPECT_EQ((*streamed)[0].error.message(), unary.status().message());
    ExpectUnchanged();
  }

  // Raw stub for what the client library cannot produce.
  grpc::Status RawIngest(const v1::Scan& scan) {
    auto channel = grpc::CreateChannel(fixture_->target(), grpc::InsecureChannelCredentials());
    auto stub = v1::MapService::NewStub(channel);
    grpc::ClientContext ctx;
    v1::ScanAck ack;
    return stub->IngestScan(&ctx, scan, &ack);
  }
  static v1::Scan RawGood() {
    const OwnedScan s = Good();
    v1::Scan m;
    m.set_robot_id(s.robot_id);
    m.set_sequence(s.sequence);
    m.mutable_pose()->mutable_rotation()->set_w(1);
    m.set_points(std::string(reinterpret_cast<const char*>(s.points.data()),
                             s.points.size() * sizeof(Point3f)));
    return m;
  }

  static ServerFixture* fixture_;
  static std::vector<OwnedScan>* scans_;
  State before_;
};

ServerFixture* BadInputTest::fixture_ = nullptr;
std::vector<OwnedScan>* BadInputTest::scans_ = nullptr;

TEST_F(BadInputTest, NonUnitQuaternion) {
  OwnedScan s = Good();
  s.pose.qw *= 0.5;
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument,
                 {"pose.rotation", "server.quaternion_tolerance"});
}

TEST_F(BadInputTest, NonFinitePose) {
  OwnedScan s = Good();
  s.pose.tx = std::nan("");
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument, {"pose.translation.x", "not finite"});
  s = Good();
  s.pose.qz = std::numeric_limits<double>::infinity();
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument, {"pose.rotation.z"});
}

TEST_F(BadInputTest, AbsurdCoordinates) {
  OwnedScan s = Good();
  s.pose.ty = 1e9;
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument,
                 {"pose.translation.y", "server.max_coordinate"});
}

TEST_F(BadInputTest, TooManyPoints) {
  OwnedScan s = Good();
  // All within the map's range: the client sends (and the server counts) every one of them.
  s.points.assign(60'000, Point3f{5, 5, -2});
  // A fixed per-request limit: INVALID_ARGUMENT (no retry outlasts it), not RESOURCE_EXHAUSTED.
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument,
                 {"points", "60000", "server.max_points_per_scan = 50000"});
}

TEST_F(BadInputTest, EmptyRobotId) {
  OwnedScan s = Good();
  s.robot_id = "";
  ExpectRejected(s.Data(), RpcCode::kInvalidArgument, {"robot_id"});
}

TEST_F(BadInputTest, MalformedPackedPoints) {
  v1::Scan m = RawGood();
  m.mutable_points()->append("\x01", 1);  // one stray byte
  const grpc::Status s = RawIngest(m);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("multiple of 12"), std::string::npos) << s.error_message();
  ExpectUnchanged();
}

TEST_F(BadInputTest, MissingPose) {
  v1::Scan m = RawGood();
  m.clear_pose();
  const grpc::Status s = RawIngest(m);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("pose"), std::string::npos) << s.error_message();
  ExpectUnchanged();
}

TEST_F(BadInputTest, RejectedScanDoesNotAdvanceTheSequence) {
  OwnedScan s = Good();
  s.sequence = 3;
  s.pose.qw = 2;
  RpcResult<ScanAck> bad = fixture_->client().Insert(s.Data());
  ASSERT_FALSE(bad.ok());
  ExpectUnchanged();
  RpcResult<MapInfo> info = fixture_->client().Info();
  ASSERT_TRUE(info.ok());
  const RobotInfo* robot = info->FindRobot("robot");
  ASSERT_NE(robot, nullptr);
  EXPECT_EQ(robot->last_sequence, 2u);
  EXPECT_GT(robot->scans_rejected, 0u);
}

TEST_F(BadInputTest, RegionTooLarge) {
  RpcResult<Raster> r = fixture_->client().QueryRegion({{0, 0, 200, 60}, {}, 1});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), RpcCode::kInvalidArgument);  // fixed limit: a retry never fits
  EXPECT_NE(r.status().message().find("2000 x 600"), std::string::npos) << r.status().ToString();
  EXPECT_NE(r.status().message().find("server.max_region_cells = 1000000"), std::string::npos);
  EXPECT_TRUE(fixture_->client().QueryRegion({{0, 0, 100, 100}, {}, 1}).ok());
  // Issue 29: the limit counts output pixels. The same 1.2M map cells at stride 2 are 300,000
  // pixels: answered, at half the resolution.
  RpcResult<Raster> coarse = fixture_->client().QueryRegion({{0, 0, 200, 60}, {}, 2});
  ASSERT_TRUE(coarse.ok()) << coarse.status().ToString();
  EXPECT_EQ(coarse->cols, 1000);
  EXPECT_EQ(coarse->rows, 300);
  // Pixels over the limit at any stride are refused, naming pixels and the stride.
  r = fixture_->client().QueryRegion({{0, 0, 600, 200}, {}, 2});  // 3000 x 1000 pixels
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), RpcCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("3000 x 1000 = 3000000 pixels at stride 2"),
            std::string::npos)
      << r.status().ToString();
  // The map cells a query reads are bounded too (time, tiles loaded): server.max_region_read_cells
  // = 16M here, so 1000 x 1000 pixels at stride 8 (64M cells) are refused.
  r = fixture_->client().QueryRegion({{0, 0, 800, 800}, {}, 8});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), RpcCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("server.max_region_read_cells = 16000000"), std::string::npos)
      << r.status().ToString();
  ExpectUnchanged();
}

TEST_F(BadInputTest, MalformedQueries) {
  Client& c = fixture_->client();
  auto code = [](const auto& r) { return r.ok() ? RpcCode::kOk : r.status().code(); };
  EXPECT_EQ(code(c.QueryRegion({{5, 0, 1, 10}, {}, 1})), RpcCode::kInvalidArgument);
  EXPECT_EQ(code(c.QueryRegion({{std::nan(""), 0, 1, 10}, {}, 1})), RpcCode::kInvalidArgument);
  EXPECT_EQ(code(c.QueryRegion({{0, 0, 1, 1}, {}, 100000})), RpcCode::kInvalidArgument);
  EXPECT_EQ(code(c.QueryRegion({{0, 0, 1, 1}, {static_cast<Layer>(42)}, 1})),
            RpcCode::kInvalidArgument);
  std::vector<std::array<double, 2>> many(1001, {0.0, 0.0});
  RpcResult<PointValues> points = c.QueryPoints(many);
  EXPECT_EQ(code(points), RpcCode::kInvalidArgument);  // fixed per-request limits
  EXPECT_NE(points.status().message().find("server.max_query_points = 1000"), std::string::npos);
  const std::array<double, 2> nan_point[] = {{std::nan(""), 1.0}};
  EXPECT_EQ(code(c.QueryPoints(nan_point)), RpcCode::kInvalidArgument);
  EXPECT_EQ(code(c.CheckPath(PathQuery{})), RpcCode::kInvalidArgument);
  PathQuery huge;
  huge.poses = {{0, 0, 0}};
  huge.radius = 1000;
  EXPECT_EQ(code(c.CheckPath(huge)), RpcCode::kInvalidArgument);
  EXPECT_EQ(code(c.ClearRegion({0, 0, std::nan(""), 1})), RpcCode::kInvalidArgument);
  ExpectUnchanged();
}

TEST_F(BadInputTest, ZzNonFinitePointsAreDroppedAndCounted) {
  // Defined last, so it runs last: it changes the map.
  OwnedScan s = Good();
  const size_t clean = s.points.size();
  OwnedScan dirty = s;
  dirty.points.push_back({kNaN, 1, 1});
  dirty.points.push_back({1, kInf, 1});
  dirty.points.insert(dirty.points.begin(), {2, 2, -kInf});
  RpcResult<ScanAck> ack = fixture_->client().Insert(dirty.Data());
  ASSERT_TRUE(ack.ok()) << ack.status().ToString();
  EXPECT_EQ(ack->status, AckStatus::kApplied);
  EXPECT_EQ(ack->counts.input, clean + 3);
  EXPECT_EQ(ack->counts.dropped_nonfinite, 3u);
  std::vector<const OwnedScan*> order = {&(*scans_)[0], &(*scans_)[1], &s};
  EXPECT_TRUE(MapsEqual(*fixture_->server().SnapshotMap(), *OfflineMap(order)));
}

// Fixed per-request limits are INVALID_ARGUMENT naming the limit: the same request never fits
// however long a client waits, so RESOURCE_EXHAUSTED, which clients retry, would mislead
// (docs/api-review.md, status codes).
TEST(FixedLimitTest, PosesWatchedTilesAndRasterRowsAreInvalidArgument) {
  ServerConfig config = TestConfig();
  config.limits.max_path_poses = 10;
  config.limits.max_watch_tiles = 4;
  config.limits.max_message_bytes = 1 << 20;
  config.limits.max_points_per_scan = 50'000;  // a scan and a chunk must fit in a message
  config.limits.region_chunk_bytes = 256 << 10;
  ServerFixture fixture(config);
  Client& c = fixture.client();
  PathQuery path;
  path.poses.assign(11, Pose2{0, 0, 0});
  path.radius = 0.3;
  RpcResult<PathCheck> p = c.CheckPath(path);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().code(), RpcCode::kInvalidArgument);
  EXPECT_NE(p.status().message().find("server.max_path_poses = 10"), std::string::npos)
      << p.status().ToString();

  std::unique_ptr<WatchSubscription> watch =
      c.Watch(WatchQuery{{-100, -100, 100, 100}, {}, false}, [](const TileUpdate&) {});
  const RpcStatus w = watch->Wait();
  EXPECT_EQ(w.code(), RpcCode::kInvalidArgument) << w.ToString();
  EXPECT_NE(w.message().find("server.max_watch_tiles = 4"), std::string::npos) << w.ToString();

  // One row of 50,000 cells x 6 layers is 1.2 MB, over a 1 MiB message.
  RpcResult<Raster> row = c.QueryRegion({{0, 0, 5000, 0.1}, {}, 1});
  ASSERT_FALSE(row.ok());
  EXPECT_EQ(row.status().code(), RpcCode::kInvalidArgument);
  EXPECT_NE(row.status().message().find("server.max_message_bytes"), std::string::npos)
      << row.status().ToString();
}

TEST(RegionBudgetTest, RastersHeldInMemoryAreBounded) {
  ServerConfig config = TestConfig();
  config.limits.max_region_bytes_in_flight = 1 << 20;
  ServerFixture fixture(config);
  // 100 x 100 cells x 6 layers x 4 bytes = 240 kB: fits.
  EXPECT_TRUE(fixture.client().QueryRegion({{0, 0, 10, 10}, {}, 1}).ok());
  // 300 x 300 cells: 2.16 MB do not.
  RpcResult<Raster> big = fixture.client().QueryRegion({{0, 0, 30, 30}, {}, 1});
  ASSERT_FALSE(big.ok());
  EXPECT_EQ(big.status().code(), RpcCode::kResourceExhausted);
  EXPECT_NE(big.status().message().find("server.max_region_bytes_in_flight = 1048576"),
            std::string::npos)
      << big.status().ToString();
  // Fewer layers or a coarser stride fit again.
  EXPECT_TRUE(fixture.client().QueryRegion({{0, 0, 30, 30}, {Layer::kElevation}, 1}).ok());
  EXPECT_TRUE(fixture.client().QueryRegion({{0, 0, 30, 30}, {}, 3}).ok());
}

}  // namespace
}  // namespace bgkmap::testing
