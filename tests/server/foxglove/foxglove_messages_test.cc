// The foxglove room without a socket: each message decoded again with the generated classes of
// proto/foxglove/schemas.proto, the advertised schemas decoded as descriptor sets, the
// protocol's JSON and frames, and the upgrade's refusals. (Foxglove's own client decodes the
// same messages in tests/interop/foxglove.)
#include <google/protobuf/descriptor.pb.h>
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "auth/token_table.h"
#include "foxglove/messages.h"
#include "foxglove/protocol.h"
#include "foxglove/schemas.pb.h"
#include "foxglove/upgrade_check.h"

namespace bgkmap::foxglove {
namespace {

// Two layers over 3 columns x 2 rows; row 0 is the north row, as a Raster runs.
Raster SmallRaster() {
  Raster r;
  r.cols = 3;
  r.rows = 2;
  r.resolution = 0.5;
  r.x0 = 10;
  r.y1 = 21;
  r.layers = {Layer::kElevation, Layer::kTraversability};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  r.data = {{1, 2, 3, 4, nan, 6}, {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f}};
  return r;
}

// Mutations caught: rows not flipped (the Grid's row 0 is the south row), the corner at the
// north edge, fields out of the raster's layer order, a stride that ignores a layer.
TEST(FoxgloveMessagesTest, GridHoldsTheRasterBitForBitSouthRowFirst) {
  const Raster raster = SmallRaster();
  ::foxglove::Grid grid;
  ASSERT_TRUE(grid.ParseFromString(EncodeGrid(raster, 1'500'000'000'250'000'000ull)));
  EXPECT_EQ(grid.frame_id(), "map");
  EXPECT_EQ(grid.timestamp().seconds(), 1'500'000'000);
  EXPECT_EQ(grid.timestamp().nanos(), 250'000'000);
  EXPECT_EQ(grid.pose().position().x(), 10.0);
  EXPECT_EQ(grid.pose().position().y(), 20.0);  // y1 - rows * resolution
  EXPECT_EQ(grid.pose().orientation().w(), 1.0);
  EXPECT_EQ(grid.column_count(), 3u);
  EXPECT_EQ(grid.cell_size().x(), 0.5);
  EXPECT_EQ(grid.cell_stride(), 8u);
  EXPECT_EQ(grid.row_stride(), 24u);
  ASSERT_EQ(grid.fields_size(), 2);
  EXPECT_EQ(grid.fields(0).name(), "elevation");
  EXPECT_EQ(grid.fields(0).offset(), 0u);
  EXPECT_EQ(grid.fields(1).name(), "traversability");
  EXPECT_EQ(grid.fields(1).offset(), 4u);
  EXPECT_EQ(grid.fields(1).type(), ::foxglove::PackedElementField::FLOAT32);
  ASSERT_EQ(grid.data().size(), 2u * 3u * 8u);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      for (int l = 0; l < 2; ++l) {
        const float want = raster.data[l][(1 - r) * 3 + c];
        EXPECT_EQ(std::memcmp(grid.data().data() + r * 24 + c * 8 + l * 4, &want, 4), 0)
            << "row " << r << " col " << c << " layer " << l;
      }
    }
  }
}

RobotScan SomeScan() {
  RobotScan scan;
  scan.robot_id = "street";
  scan.stamp = {1700000000, 5};
  // 90 degrees about z.
  scan.pose = Pose::FromQuaternion(std::sqrt(0.5), 0, 0, std::sqrt(0.5), 1, 2, 3);
  scan.points = {{1, 2, 3}, {-4, 5.5f, 6}};
  return scan;
}

TEST(FoxgloveMessagesTest, TransformsAndCloudCarryTheScansPose) {
  const auto scan = std::make_shared<const RobotScan>(SomeScan());
  ::foxglove::FrameTransforms transforms;
  ASSERT_TRUE(transforms.ParseFromString(EncodeTransforms({scan})));
  ASSERT_EQ(transforms.transforms_size(), 1);
  const ::foxglove::FrameTransform& t = transforms.transforms(0);
  EXPECT_EQ(t.parent_frame_id(), "map");
  EXPECT_EQ(t.child_frame_id(), "street");
  EXPECT_EQ(t.timestamp().seconds(), 1700000000);
  EXPECT_EQ(t.timestamp().nanos(), 5);
  EXPECT_EQ(t.translation().y(), 2.0);
  EXPECT_NEAR(t.rotation().z(), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(t.rotation().w(), std::sqrt(0.5), 1e-12);

  ::foxglove::PointCloud cloud;
  ASSERT_TRUE(cloud.ParseFromString(EncodeScan(*scan)));
  EXPECT_EQ(cloud.frame_id(), "street");  // placed by the transform above, same stamp
  EXPECT_EQ(cloud.timestamp().seconds(), 1700000000);
  EXPECT_EQ(cloud.timestamp().nanos(), 5);
  EXPECT_EQ(cloud.pose().position().z(), 0.0);
  EXPECT_EQ(cloud.pose().orientation().w(), 1.0);
  EXPECT_EQ(cloud.point_stride(), 12u);
  ASSERT_EQ(cloud.fields_size(), 3);
  EXPECT_EQ(cloud.fields(2).name(), "z");
  EXPECT_EQ(cloud.fields(2).offset(), 8u);
  ASSERT_EQ(cloud.data().size(), 24u);
  float y1 = 0;
  std::memcpy(&y1, cloud.data().data() + 12 + 4, 4);
  EXPECT_EQ(y1, 5.5f);
}

// The advertised schema is a FileDescriptorSet (base64) that holds the message with Foxglove's
// field numbers, its imports first (protobufjs and Foxglove resolve them in order).
TEST(FoxgloveMessagesTest, AdvertisedSchemasAreDescriptorSetsWithFoxglovesFieldNumbers) {
  const std::vector<Channel> channels = Channels();
  ASSERT_EQ(channels.size(), 3u);
  EXPECT_EQ(channels[0].topic, "/map");
  EXPECT_EQ(channels[0].schema_name, "foxglove.Grid");
  EXPECT_EQ(channels[1].schema_name, "foxglove.FrameTransforms");
  EXPECT_EQ(channels[2].schema_name, "foxglove.PointCloud");
  const std::string& b64 = channels[0].schema_base64;
  std::string bytes(b64.size(), '\0');
  const int n = EVP_DecodeBlock(reinterpret_cast<unsigned char*>(bytes.data()),
                                reinterpret_cast<const unsigned char*>(b64.data()),
                                static_cast<int>(b64.size()));
  ASSERT_GT(n, 0);
  bytes.resize(static_cast<size_t>(n) - std::count(b64.end() - 2, b64.end(), '='));
  google::protobuf::FileDescriptorSet set;
  ASSERT_TRUE(set.ParseFromString(bytes));
  ASSERT_EQ(set.file_size(), 2);
  EXPECT_EQ(set.file(0).name(), "google/protobuf/timestamp.proto");
  const google::protobuf::FileDescriptorProto& file = set.file(1);
  const google::protobuf::DescriptorProto* grid = nullptr;
  for (const auto& m : file.message_type()) {
    if (m.name() == "Grid") grid = &m;
  }
  ASSERT_NE(grid, nullptr);
  const std::vector<std::pair<std::string, int>> want = {
      {"timestamp", 1},  {"frame_id", 2},    {"pose", 3},   {"column_count", 4}, {"cell_size", 5},
      {"row_stride", 6}, {"cell_stride", 7}, {"fields", 8}, {"data", 9}};
  ASSERT_EQ(grid->field_size(), static_cast<int>(want.size()));
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(grid->field(static_cast<int>(i)).name(), want[i].first);
    EXPECT_EQ(grid->field(static_cast<int>(i)).number(), want[i].second);
  }
}

TEST(FoxgloveProtocolTest, ClientMessagesParsedOrRefusedWithTheReason) {
  ClientMessage m = ParseClientMessage(
      R"({"op":"subscribe","subscriptions":[{"id":7,"channelId":1},{"id":8,"channelId":3}]})");
  ASSERT_EQ(m.op, ClientMessage::Op::kSubscribe) << m.error;
  ASSERT_EQ(m.subscribe.size(), 2u);
  EXPECT_EQ(m.subscribe[1].id, 8u);
  EXPECT_EQ(m.subscribe[1].channel_id, 3u);
  m = ParseClientMessage(R"({"op":"unsubscribe","subscriptionIds":[7]})");
  ASSERT_EQ(m.op, ClientMessage::Op::kUnsubscribe);
  EXPECT_EQ(m.unsubscribe, std::vector<uint32_t>{7});
  auto error = [](const char* text) { return ParseClientMessage(text).error; };
  EXPECT_EQ(error("{nope"), "not a JSON message");
  EXPECT_EQ(error("[1]"), "a message must be a JSON object");
  EXPECT_EQ(error(R"({"subscriptions":[]})"), "a message needs a string 'op'");
  EXPECT_NE(error(R"({"op":"advertise","channels":[]})").find("'advertise' is not offered"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})")
                .find("integer 'id' and 'channelId'"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe"})").find("'subscriptions' must be an array"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"unsubscribe","subscriptionIds":["7"]})").find("array of integers"),
            std::string::npos);
}

TEST(FoxgloveProtocolTest, MessageDataFrameIsOpcodeIdTimeThenPayload) {
  const std::string frame = MessageDataFrame(0x01020304, 0x1122334455667788ull, "xy");
  const std::string want("\x01\x04\x03\x02\x01\x88\x77\x66\x55\x44\x33\x22\x11xy", 15);
  EXPECT_EQ(frame, want);
  EXPECT_NE(StatusJson(StatusLevel::kError, "bad \xff").find("\"level\":2"), std::string::npos);
}

class UpgradeCheckTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = (std::filesystem::temp_directory_path() /
             ("bgkmap_foxglove_tokens_" + std::to_string(getpid()) + ".yaml"))
                .string();
    std::ofstream(path_) << "tokens:\n"
                         << "  - {name: viewer, sha256: " << Sha256Hex("planner-token")
                         << ", role: planner}\n"
                         << "  - {name: lidar, sha256: " << Sha256Hex("robot-token")
                         << ", role: robot, robots: [r]}\n";
    Result<std::unique_ptr<TokenTable>> t = TokenTable::Load(path_, {1, 1});
    ASSERT_TRUE(t.ok()) << t.status().ToString();
    tokens_ = std::move(t).value();
  }
  void TearDown() override { std::filesystem::remove(path_); }

  std::optional<Refusal> Check(std::string_view authorization, std::string_view target = "/",
                               size_t clients = 0) {
    return CheckUpgrade({true, "foxglove.websocket.v1", authorization, target}, tokens_.get(),
                        clients, 2);
  }
  std::string path_;
  std::unique_ptr<TokenTable> tokens_;
};

TEST_F(UpgradeCheckTest, RefusesWithoutTheSubprotocolATokenThatMayWatchOrAFreeSlot) {
  EXPECT_EQ(Check("Bearer planner-token"), std::nullopt);
  EXPECT_EQ(Check("", "/?x=1&token=planner-token"), std::nullopt);  // a viewer's URL
  const std::optional<Refusal> none = Check("");
  ASSERT_TRUE(none.has_value());
  EXPECT_EQ(none->status, 401);
  EXPECT_EQ(Check("Bearer wrong")->status, 401);
  const std::optional<Refusal> robot = Check("Bearer robot-token");
  ASSERT_TRUE(robot.has_value());
  EXPECT_EQ(robot->status, 403);
  EXPECT_NE(robot->reason.find("'lidar' (role robot) may not watch"), std::string::npos);
  EXPECT_EQ(Check("Bearer planner-token", "/", 2)->status, 503);
  EXPECT_EQ(CheckUpgrade({false, "", "", "/"}, nullptr, 0, 2)->status, 400);
  const std::optional<Refusal> other =
      CheckUpgrade({true, "chat, superchat", "", "/"}, nullptr, 0, 2);
  ASSERT_TRUE(other.has_value());
  EXPECT_EQ(other->status, 400);
  EXPECT_NE(other->reason.find("foxglove.websocket.v1"), std::string::npos);
  EXPECT_EQ(CheckUpgrade({true, "x, foxglove.websocket.v1", "", "/"}, nullptr, 0, 2), std::nullopt);
}

// Mutation caught: GridGeometry::BoxCovering (closed, no snap) instead: -20 / 0.1 starts a cell
// early and 20 ends a cell late.
TEST(FoxgloveMessagesTest, RegionCellsAreTheRegionQuerysHalfOpenBox) {
  const GridGeometry g(0.1, 64);
  const CellBox box = RegionCells(g, -20, -20, 20, 20.05);
  EXPECT_EQ(box.min.x, -200);
  EXPECT_EQ(box.min.y, -200);
  EXPECT_EQ(box.max.x, 199);
  EXPECT_EQ(box.max.y, 200);
}

TEST(UpgradeTokenTest, TokenFromTheQueryIsPercentDecoded) {
  EXPECT_EQ(TokenFromTarget("/?token=a%2Bb&x=1"), "a+b");
  EXPECT_EQ(TokenFromTarget("/?xtoken=a"), "");
  EXPECT_EQ(TokenFromTarget("/"), "");
}

}  // namespace
}  // namespace bgkmap::foxglove
