// Transient objects through the real server (docs/semantics.md, "Transient objects"): the ground
// kept aside is part of the stored tiles and of what the log replays. A box appears on ground
// the map saw, is seen for 0.2 s, then moves closer and hides where it stood. The served map is
// the offline map of the same scans and stamps, bit for bit, across a graceful restart between
// the appearance and its expiry (the kept ground must come back from the checkpoint) and after
// kill -9 (it must come back from the log).
// Mutations checked: EncodeTile not writing the kept ground (the restart's map keeps the box);
// the server not stamping the scans (nothing is kept aside: the rule never acts).
#include <gtest/gtest.h>
#include <signal.h>

#include <cstring>
#include <string>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmapd_process.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

constexpr double kSensorZ = 1.0;

// Flat ground 3-8 m ahead of a sensor at (0.05, 0.05, 1); with the box (0.5 x 1 m, 1 m tall) at
// 5.5-6 m and no return from its shadow; or with it moved to 4-4.5 m (1.2 m tall), hiding where
// it stood.
enum class World { kBare, kBox, kBoxMovedCloser };

std::vector<Point3f> SensorFramePoints(World world) {
  std::vector<Point3f> pts;
  for (int i = 0; i < 50; ++i) {
    for (int j = 0; j < 30; ++j) {
      const float x = 3.05f + 0.1f * i, y = -1.45f + 0.1f * j;
      const bool lane = y > -0.5f && y < 0.5f;
      float z = 0.0f;
      if (world == World::kBox && lane && x > 5.5f && x < 6.0f) z = 1.0f;
      if (world == World::kBox && lane && x > 6.0f) continue;
      if (world == World::kBoxMovedCloser && lane && x > 4.0f && x < 4.5f) z = 1.2f;
      if (world == World::kBoxMovedCloser && lane && x > 4.5f) continue;
      pts.push_back({x - 0.05f, y - 0.05f, z - static_cast<float>(kSensorZ)});
    }
  }
  return pts;
}

// 5 bare scans, 2 with the box, 15 with it moved closer; 10 Hz.
std::vector<OwnedScan> Scans() {
  std::vector<OwnedScan> scans;
  for (int k = 0; k < 22; ++k) {
    OwnedScan s;
    s.robot_id = "alpha";
    s.sequence = k + 1;
    s.pose.tx = 0.05;
    s.pose.ty = 0.05;
    s.pose.tz = kSensorZ;
    s.points = SensorFramePoints(k < 5   ? World::kBare
                                 : k < 7 ? World::kBox
                                         : World::kBoxMovedCloser);
    scans.push_back(std::move(s));
  }
  return scans;
}

int64_t StampOf(int k) { return int64_t{1'764'000'000} * 1'000'000'000 + (k + 1) * 100'000'000LL; }

void InsertAll(Client& client, const std::vector<OwnedScan>& scans, size_t from, size_t to) {
  for (size_t k = from; k < to; ++k) {
    ScanData d = scans[k].Data();
    d.stamp_ns = StampOf(static_cast<int>(k));
    RpcResult<ScanAck> ack = client.Insert(d);
    ASSERT_TRUE(ack.ok() && ack->status == AckStatus::kApplied) << "scan " << k;
  }
}

TEST(TransientPersistenceTest, KeptGroundSurvivesACheckpointAndReplaysBitwiseAfterSigkill) {
  TempDir dir("bgkmap_transient");
  const std::vector<std::string> args = {"--data-dir", dir.str(), "--set", "transient_confirm_s=2"};
  const std::vector<OwnedScan> scans = Scans();
  const MetricBox box{-1.0, -3.0, 9.0, 3.0};
  MapParams params;
  params.transient_confirm_s = 2;

  {  // The appearance, then a graceful stop: the ground kept aside is only in the checkpoint.
    BgkmapdProcess server(args);
    ASSERT_TRUE(server.started());
    Client client(server.target());
    InsertAll(client, scans, 0, 7);
    server.Signal(SIGTERM);
    EXPECT_EQ(server.Wait(), 0);
  }
  Raster served;
  {
    BgkmapdProcess server(args);
    ASSERT_TRUE(server.started());
    Client client(server.target());
    InsertAll(client, scans, 7, scans.size());
    RpcResult<Raster> r = client.QueryRegion({box, {}, 1});
    ASSERT_TRUE(r.ok());
    served = *r;
    server.Signal(SIGKILL);  // the last 15 scans only in the log
    server.Wait();
  }

  std::unique_ptr<TerrainMap> offline = TerrainMap::Create(params).value();
  for (size_t k = 0; k < scans.size(); ++k) {
    ASSERT_TRUE(offline
                    ->IntegrateScan(PointsAsIntegrated(scans[k], params), WirePose(scans[k].pose),
                                    false, StampOf(static_cast<int>(k)))
                    .ok());
  }
  EXPECT_TRUE(BitwiseEqual(served, OfflineRegion(*offline, box)));
  // The rule acted: the box's place is ground again, which without it stays the box.
  EXPECT_EQ(offline->EstimateAt(5.75, 0.05).state, CellState::kTraversable);
  std::unique_ptr<TerrainMap> without = TerrainMap::Create(MapParams{}).value();
  for (size_t k = 0; k < scans.size(); ++k) {
    ASSERT_TRUE(without
                    ->IntegrateScan(PointsAsIntegrated(scans[k], params), WirePose(scans[k].pose),
                                    false, StampOf(static_cast<int>(k)))
                    .ok());
  }
  EXPECT_EQ(without->EstimateAt(5.75, 0.05).state, CellState::kNonTraversable);

  BgkmapdProcess server(args);
  ASSERT_TRUE(server.started());
  const std::string line = server.FindLine("event=recovered");
  EXPECT_NE(line.find("scans_replayed=15"), std::string::npos) << line;
  RpcResult<Raster> after = Client(server.target()).QueryRegion({box, {}, 1});
  ASSERT_TRUE(after.ok());
  EXPECT_TRUE(BitwiseEqual(served, *after));
}

}  // namespace
}  // namespace bgkmap::testing
