// Pose corrections through the real server (issue: pose corrections): a drive mapped with
// drifting odometry, corrected to the true poses, equals the map built from the true poses,
// exactly: also with a second robot in the region, while the robot streams on, and across a
// restart. Removing a robot's scans gives the map without them. Bad requests change nothing.
#include <gtest/gtest.h>
#include <signal.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cstdio>
#include <thread>

#include "bgkmapd_process.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

// Odometry that drifts: 4 cm, 2 cm and 0.3 degrees of yaw more per scan.
ScanPose Drifted(const ScanPose& truth, uint64_t k) {
  Pose p = WirePose(truth);
  p.rotation =
      Eigen::AngleAxisd(0.005 * static_cast<double>(k), Eigen::Vector3d::UnitZ()) * p.rotation;
  p.translation += Eigen::Vector3d(0.04, 0.02, 0.0) * static_cast<double>(k);
  return ScanPose::FromPose(p);
}

// A drive of `n` scans of robot `id` (sub-scans of the street scans): true and drifted poses.
struct DriveScans {
  std::vector<OwnedScan> truth, drifted;
  DriveScans(const std::string& id, int parts, size_t n) {
    truth = SubScans(id, parts, n);
    drifted = truth;
    for (OwnedScan& s : drifted) s.pose = Drifted(s.pose, s.sequence);
  }
  // Drifted poses, corrected (to the truth) from sequence `from` on.
  std::vector<OwnedScan> CorrectedFrom(uint64_t from) const {
    std::vector<OwnedScan> out = drifted;
    for (OwnedScan& s : out) {
      if (s.sequence >= from) s.pose = truth[s.sequence - 1].pose;
    }
    return out;
  }
  std::vector<std::pair<uint64_t, ScanPose>> TruePosesFrom(uint64_t from) const {
    std::vector<std::pair<uint64_t, ScanPose>> out;
    for (const OwnedScan& s : truth) {
      if (s.sequence >= from) out.emplace_back(s.sequence, s.pose);
    }
    return out;
  }
};

void Send(Client& client, const std::vector<const OwnedScan*>& scans) {
  std::vector<ScanData> data;
  for (const OwnedScan* s : scans) data.push_back(s->Data());
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
  for (const ScanAck& a : *acks) ASSERT_EQ(a.status, AckStatus::kApplied) << a.error.ToString();
}

std::vector<const OwnedScan*> Pointers(const std::vector<OwnedScan>& scans) {
  std::vector<const OwnedScan*> out;
  for (const OwnedScan& s : scans) out.push_back(&s);
  return out;
}

// Interleaves two robots' scans: a1 b1 a2 b2 ...
std::vector<const OwnedScan*> Interleaved(const std::vector<OwnedScan>& a,
                                          const std::vector<OwnedScan>& b) {
  std::vector<const OwnedScan*> out;
  for (size_t i = 0; i < std::max(a.size(), b.size()); ++i) {
    if (i < a.size()) out.push_back(&a[i]);
    if (i < b.size()) out.push_back(&b[i]);
  }
  return out;
}

ServerConfig StoreConfig(const TempDir& dir) {
  ServerConfig c = TestConfig();
  c.storage.data_dir = dir.Sub("map");
  c.storage.durability = "periodic";
  c.storage.checkpoint_interval_s = 0.2;  // several retained checkpoints within the drive
  return c;
}

// The map an in-memory server builds from `scans`, in order.
std::unique_ptr<TerrainMap> ReferenceMap(const std::vector<const OwnedScan*>& scans) {
  ServerFixture reference;
  Send(reference.client(), scans);
  return reference.server().SnapshotMap();
}

constexpr int kParts = 12;
constexpr size_t kScans = 36;

TEST(PoseCorrection, CorrectedDriveEqualsTheMapFromTruePosesExactly) {
  const DriveScans drive("robot-a", kParts, kScans);
  TempDir dir;
  auto owned = std::make_unique<ServerFixture>(StoreConfig(dir));
  ServerFixture& fixture = *owned;
  Send(fixture.client(), Pointers(drive.drifted));
  const auto drifted = fixture.server().SnapshotMap();
  RpcResult<CorrectionResult> r = fixture.client().CorrectPoses("robot-a", drive.TruePosesFrom(10));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->scans_revised, kScans - 9);
  EXPECT_GT(r->tiles_changed, 0u);
  EXPECT_LE(r->records_replayed, r->records_in_history);
  const std::vector<OwnedScan> corrected = drive.CorrectedFrom(10);
  const auto expected = ReferenceMap(Pointers(corrected));
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *expected));
  EXPECT_FALSE(MapsEqual(*drifted, *expected));  // the drift did matter
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok());

  // A restart rebuilds the same corrected map (the correction is in the log, or checkpointed).
  owned.reset();
  ServerFixture restarted(StoreConfig(dir));
  EXPECT_TRUE(MapsEqual(*restarted.server().SnapshotMap(), *expected));
}

TEST(PoseCorrection, TwoRobotsInTheRegion) {
  const DriveScans a("robot-a", kParts, kScans), b("robot-b", kParts, kScans);
  TempDir dir;
  ServerFixture fixture(StoreConfig(dir));
  Send(fixture.client(), Interleaved(a.drifted, b.truth));
  ASSERT_TRUE(fixture.client().CorrectPoses("robot-a", a.TruePosesFrom(5)).ok());
  const std::vector<OwnedScan> corrected = a.CorrectedFrom(5);
  EXPECT_TRUE(
      MapsEqual(*fixture.server().SnapshotMap(), *ReferenceMap(Interleaved(corrected, b.truth))));
}

TEST(PoseCorrection, WhileTheSameRobotStreamsOn) {
  const DriveScans drive("robot-a", kParts, kScans);
  TempDir dir;
  ServerFixture fixture(StoreConfig(dir));
  const std::vector<const OwnedScan*> all = Pointers(drive.drifted);
  const std::vector<const OwnedScan*> first(all.begin(), all.begin() + 20);
  const std::vector<const OwnedScan*> rest(all.begin() + 20, all.end());
  Send(fixture.client(), first);
  // Scans 21.. stream on another connection while scans 5..20 are corrected.
  std::thread streamer([&] {
    std::unique_ptr<Client> robot = fixture.NewClient();
    Send(*robot, rest);
  });
  std::vector<std::pair<uint64_t, ScanPose>> poses = drive.TruePosesFrom(5);
  poses.resize(16);  // 5..20
  RpcResult<CorrectionResult> r = fixture.client().CorrectPoses("robot-a", poses);
  streamer.join();
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::vector<OwnedScan> expected = drive.drifted;
  for (const auto& [sequence, pose] : poses) expected[sequence - 1].pose = pose;
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *ReferenceMap(Pointers(expected))));
}

TEST(PoseCorrection, RemovedScansLeaveTheMapWithoutThem) {
  const DriveScans a("robot-a", kParts, 24), b("robot-b", kParts, 24);
  TempDir dir;
  ServerFixture fixture(StoreConfig(dir));
  Send(fixture.client(), Interleaved(a.truth, b.truth));
  RpcResult<CorrectionResult> r = fixture.client().RemoveScans("robot-b", 6, 17);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->scans_revised, 12u);
  // The same order, without them (the order matters: a scan reads the map as it was).
  std::vector<const OwnedScan*> kept;
  for (const OwnedScan* s : Interleaved(a.truth, b.truth)) {
    if (s->robot_id == "robot-b" && s->sequence >= 6 && s->sequence <= 17) continue;
    kept.push_back(s);
  }
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *ReferenceMap(kept)));
  // Removed means gone: correcting one of them is refused.
  std::vector<std::pair<uint64_t, ScanPose>> one = {{7, b.truth[6].pose}};
  EXPECT_EQ(fixture.client().CorrectPoses("robot-b", one).status().code(),
            RpcCode::kInvalidArgument);
}

TEST(PoseCorrection, BadRequestsGetOneClearErrorAndChangeNothing) {
  const DriveScans drive("robot-a", kParts, 12);
  TempDir dir;
  ServerFixture fixture(StoreConfig(dir));
  Send(fixture.client(), Pointers(drive.drifted));
  const auto before = fixture.server().SnapshotMap();
  Client& c = fixture.client();
  auto expect = [&](RpcResult<CorrectionResult> r, RpcCode code, const std::string& words) {
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), code) << r.status().ToString();
    EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().ToString();
  };
  expect(c.CorrectPoses("nobody", drive.TruePosesFrom(1)), RpcCode::kNotFound, "not a known");
  expect(c.CorrectPoses("robot-a", {{99, drive.truth[0].pose}}), RpcCode::kInvalidArgument,
         "never ingested");
  ScanPose nan = drive.truth[0].pose;
  nan.tx = std::nan("");
  expect(c.CorrectPoses("robot-a", {{1, nan}}), RpcCode::kInvalidArgument, "pose.translation.x");
  ScanPose skewed = drive.truth[0].pose;
  skewed.qw *= 2;  // not a unit quaternion
  expect(c.CorrectPoses("robot-a", {{1, skewed}}), RpcCode::kInvalidArgument, "quaternion");
  expect(c.CorrectPoses("robot-a", {{1, drive.truth[0].pose}, {1, drive.truth[0].pose}}),
         RpcCode::kInvalidArgument, "listed twice");
  expect(c.CorrectPoses("robot-a", {}), RpcCode::kInvalidArgument, "empty");
  expect(c.RemoveScans("robot-a", 9, 3), RpcCode::kInvalidArgument, "first_sequence");
  expect(c.RemoveScans("robot-a", 50, 60), RpcCode::kInvalidArgument, "no scan");
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *before));

  // A map in memory keeps no scans to correct.
  ServerFixture memory;
  Send(memory.client(), Pointers(drive.drifted));
  expect(memory.client().CorrectPoses("robot-a", drive.TruePosesFrom(1)),
         RpcCode::kFailedPrecondition, "storage.data_dir");
}

TEST(PoseCorrection, AScanNoLongerRetainedIsRefusedNamingTheOldestRetainedOne) {
  const DriveScans drive("robot-a", kParts, kScans);
  TempDir dir;
  ServerConfig config = StoreConfig(dir);
  config.storage.retention_mb = 1;  // a few sub-scans' raw points
  config.storage.checkpoint_interval_s = 0.02;
  ServerFixture fixture(config);
  for (const OwnedScan& s : drive.drifted) {
    Send(fixture.client(), {&s});
    std::this_thread::sleep_for(std::chrono::milliseconds(60));  // a checkpoint after each
  }
  RpcResult<CorrectionResult> r = fixture.client().CorrectPoses("robot-a", drive.TruePosesFrom(1));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), RpcCode::kFailedPrecondition) << r.status().ToString();
  EXPECT_NE(r.status().message().find("oldest retained scan is sequence"), std::string::npos)
      << r.status().ToString();
  // The newest scans are still retained, and can be corrected.
  EXPECT_TRUE(fixture.client().CorrectPoses("robot-a", drive.TruePosesFrom(kScans)).ok());
}

// kill -9 while a correction runs: the restarted map is the map before it or after it, never a
// mix, and an acknowledged correction is kept. Kills land at several moments of the correction.
TEST(PoseCorrection, Kill9DuringACorrectionRecoversBeforeOrAfterIt) {
  const DriveScans drive("robot-a", kParts, kScans);
  const std::vector<OwnedScan> corrected = drive.CorrectedFrom(4);
  const auto before_map = ReferenceMap(Pointers(drive.drifted));
  const auto after_map = ReferenceMap(Pointers(corrected));
  MetricBox box = KnownBox(*before_map);
  const MetricBox b2 = KnownBox(*after_map);
  box = {std::min(box.min_x, b2.min_x), std::min(box.min_y, b2.min_y),
         std::max(box.max_x, b2.max_x), std::max(box.max_y, b2.max_y)};
  const Raster before = OfflineRegion(*before_map, box), after = OfflineRegion(*after_map, box);
  int recovered_before = 0, recovered_after = 0;
  for (int delay_ms : {0, 40, 80, 120, 160, 240, 1500}) {
    TempDir dir("bgkmap_correct_kill");
    const std::vector<std::string> args = {"--data-dir", dir.str(), "--set",
                                           "storage.checkpoint_interval_s=0.1"};
    std::atomic<bool> acknowledged{false};
    {
      BgkmapdProcess server(args);
      ASSERT_TRUE(server.started());
      Client client(server.target());
      Send(client, Pointers(drive.drifted));
      std::thread corrector([&] {
        Client c(server.target());
        acknowledged = c.CorrectPoses("robot-a", drive.TruePosesFrom(4)).ok();
      });
      std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
      server.Signal(SIGKILL);
      server.Wait();
      corrector.join();
    }
    BgkmapdProcess server(args);
    ASSERT_TRUE(server.started());
    Client client(server.target());
    RpcResult<Raster> map = client.QueryRegion({box, {}, 1});
    ASSERT_TRUE(map.ok()) << map.status().ToString();
    const bool is_before = RastersMatch(*map, before, 0.0);
    const bool is_after = RastersMatch(*map, after, 0.0);
    EXPECT_TRUE(is_before || is_after) << "a mix after a kill at " << delay_ms << " ms";
    if (acknowledged) {
      EXPECT_TRUE(is_after) << "an acknowledged correction was lost";
    }
    recovered_before += is_before ? 1 : 0;
    recovered_after += is_after ? 1 : 0;
  }
  std::printf("kill -9 during a correction: %d trials recovered the map before it, %d after\n",
              recovered_before, recovered_after);
}

}  // namespace
}  // namespace bgkmap::testing
