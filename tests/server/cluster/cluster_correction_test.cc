// CorrectPoses and RemoveScans on a bgkmap cluster (real nats-server processes) against a single
// server with a store (retained scans) fed the same calls in the same order: after each
// correction, removal, second correction of scans already corrected, and scans sent after them,
// the regions and points through either shard are the single server's bit for bit; also when a
// shard is killed with -9 just before the corrections (its partitions are taken over from their
// checkpoints, replayed and rebuilt at the corrections' entries).
//
// An export through a shard after the corrections is the single server's archive byte for byte
// (but for the robots' table only a server with a store writes), tiles' versions included; Info's
// correction counters on either shard are the single server's.
//
// Mutations checked by hand (each makes a test below fail):
//   - the rebuild replaying the scans with the poses they were sent with (revisions ignored);
//   - a removed scan integrated anyway in the rebuild;
//   - the correction entry naming only the partitions of the scans as first sent (not the
//     partitions their corrected poses reach): the scans moved 25 m are missing;
//   - no stamps of the affected tiles (a rebuilt tile keeps its last replayed entry's version),
//     or stamps only on the rebuilt partitions, or none in a rebuild's replay of an earlier
//     correction: the archives differ;
//   - refusals not recorded in the log: Info's failed corrections differ;
//   - the affected tiles not grown over the entries appended while a correction was resolved:
//     CorrectionWhileScansStreamIn failed 2 runs of 3 (those whose entry landed after several
//     streamed scans).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/server/map_server.h"
#include "bgkmap/storage/map_archive.h"
#include "bgkmap/v1/map_service.grpc.pb.h"
#include "bgkmapd_process.h"
#include "cluster_support.h"
#include "nats_cluster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

// A single server whose store retains the scans (storage.retention_mb's default), with
// checkpoints within the drive, as tests/server/rpc/pose_correction_test.cc runs it.
ServerConfig StoreConfig(const TempDir& dir) {
  ServerConfig c = TestConfig();
  c.storage.data_dir = dir.Sub("single");
  c.storage.durability = "periodic";
  c.storage.checkpoint_interval_s = 0.2;
  return c;
}

// The two robots' scans with r1's odometry drifting (6 cm and 3 cm more per scan).
std::vector<OwnedScan> Drifted() {
  std::vector<OwnedScan> out = TwoRobots();
  for (OwnedScan& s : out) {
    if (s.robot_id != "r1") continue;
    s.pose.tx += 0.06 * static_cast<double>(s.sequence);
    s.pose.ty += 0.03 * static_cast<double>(s.sequence);
  }
  return out;
}

// r1's true poses (shifted by `dx` metres) for sequences first..last.
std::vector<std::pair<uint64_t, ScanPose>> R1Poses(uint64_t first, uint64_t last, double dx = 0) {
  std::vector<std::pair<uint64_t, ScanPose>> out;
  for (const OwnedScan& s : TwoRobots()) {
    if (s.robot_id != "r1" || s.sequence < first || s.sequence > last) continue;
    ScanPose p = s.pose;
    p.tx += dx;
    out.emplace_back(s.sequence, p);
  }
  return out;
}

// The same call's answers: both OK with the same count of scans revised, or the same refusal.
::testing::AssertionResult SameOutcome(const RpcResult<CorrectionResult>& shard,
                                       const RpcResult<CorrectionResult>& single) {
  if (shard.ok() != single.ok()) {
    return ::testing::AssertionFailure()
           << "shard: " << (shard.ok() ? "OK" : shard.status().message())
           << ", single: " << (single.ok() ? "OK" : single.status().message());
  }
  if (!shard.ok()) {
    if (shard.status().code() != single.status().code() ||
        shard.status().message() != single.status().message()) {
      return ::testing::AssertionFailure()
             << "shard: " << shard.status().message() << ", single: " << single.status().message();
    }
    return ::testing::AssertionSuccess() << "both refused: " << shard.status().message();
  }
  if (shard->scans_revised != single->scans_revised) {
    return ::testing::AssertionFailure()
           << shard->scans_revised << " scans revised, single " << single->scans_revised;
  }
  return ::testing::AssertionSuccess();
}

std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Archive `in` written again to `out` without its robots' table (which a single server with a
// store writes and a shard, like a single server without one, does not).
void WithoutRobots(const std::string& in, const std::string& out) {
  Result<std::unique_ptr<storage::MapArchiveReader>> reader = storage::MapArchiveReader::Open(in);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  storage::MapMetadata metadata = (*reader)->metadata();
  metadata.robot_sequences.clear();
  Result<std::unique_ptr<storage::MapArchiveWriter>> writer =
      storage::MapArchiveWriter::Create(out, metadata);
  ASSERT_TRUE(writer.ok()) << writer.status().ToString();
  TileKey key;
  std::unique_ptr<Tile> tile;
  for (;;) {
    Result<bool> more = (*reader)->Next(&key, &tile);
    ASSERT_TRUE(more.ok()) << more.status().ToString();
    if (!*more) break;
    ASSERT_TRUE((*writer)->Add(key, *tile).ok());
  }
  ASSERT_TRUE((*writer)->Finish().ok());
}

// ExportMap through `shard` and through the single server: the same bytes, but for the single
// server's robots' table (the shard's archive, written again the same way, is its own bytes).
::testing::AssertionResult SameExport(Client& shard, Client& single, const TempDir& dir,
                                      const std::string& name) {
  const std::string got = dir.Sub(name + "-shard.bgkmap"), want = dir.Sub(name + "-single.bgkmap");
  RpcResult<ExportResult> a = shard.ExportMap(std::nullopt, got);
  RpcResult<ExportResult> b = single.ExportMap(std::nullopt, want);
  if (!a.ok() || !b.ok()) return ::testing::AssertionFailure() << "an export failed";
  WithoutRobots(want, want + ".norobots");
  WithoutRobots(got, got + ".again");
  const std::string x = FileBytes(got), y = FileBytes(want + ".norobots");
  if (x != FileBytes(got + ".again")) {
    return ::testing::AssertionFailure() << "the archive does not survive being written again";
  }
  if (x == y && !x.empty()) return ::testing::AssertionSuccess() << x.size() << " bytes";
  size_t i = 0;
  while (i < x.size() && i < y.size() && x[i] == y[i]) ++i;
  return ::testing::AssertionFailure()
         << name << ": the shard's archive (" << x.size() << " bytes) and the single server's ("
         << y.size() << " bytes) differ from byte " << i;
}

// Info's correction counters (the client library does not carry them).
v1::Corrections Corrections(const std::string& target) {
  auto stub =
      v1::MapService::NewStub(grpc::CreateChannel(target, grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  v1::InfoResponse response;
  EXPECT_TRUE(stub->Info(&context, v1::InfoRequest(), &response).ok());
  return response.corrections();
}

// A shard's counters equal the single server's (all but last_seconds, a duration).
::testing::AssertionResult SameCorrections(const std::string& shard, const std::string& single) {
  const v1::Corrections a = Corrections(shard), b = Corrections(single);
  if (a.in_progress() == b.in_progress() && a.applied() == b.applied() &&
      a.failed() == b.failed() && a.scans_revised() == b.scans_revised() && a.last_seconds() > 0 &&
      b.last_seconds() > 0) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure()
         << "shard: " << a.ShortDebugString() << "; single: " << b.ShortDebugString();
}

TEST(ClusterCorrectionTest, CorrectionsAndRemovalsAsOneServer) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = Drifted();
  const size_t most = scans.size() - 4;  // the last two of each robot come after the corrections
  const std::vector<OwnedScan> first(scans.begin(), scans.begin() + static_cast<long>(most));
  Reference ref(first, StoreConfig(dir));
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  Client& single = ref.single.client();
  InsertByRobot(a.client(), b.client(), scans, 0, most);
  ASSERT_TRUE(SameAnswers(a.client(), ref));
  const Raster drifted = ref.Region(ref.box, 1);

  // r1's scans 3..8 corrected to their true poses, through b (r1 sent through a).
  EXPECT_TRUE(SameOutcome(b.client().CorrectPoses("r1", R1Poses(3, 8)),
                          single.CorrectPoses("r1", R1Poses(3, 8))));
  EXPECT_FALSE(SameBits(drifted, ref.Region(ref.box, 1))) << "the correction changed nothing";
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));

  // r2's scans 4..6 removed, through a.
  EXPECT_TRUE(SameOutcome(a.client().RemoveScans("r2", 4, 6), single.RemoveScans("r2", 4, 6)));
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));
  // Its affected tiles reach partitions it does not rebuild (later scans read removed cells).
  EXPECT_TRUE(SameExport(a.client(), single, dir, "removed"));

  // r1's scans 5..10 corrected again, 25 m further (5..8 were corrected already): into
  // partitions no scan reached before.
  EXPECT_TRUE(SameOutcome(a.client().CorrectPoses("r1", R1Poses(5, 10, 25.0)),
                          single.CorrectPoses("r1", R1Poses(5, 10, 25.0))));
  ref.box = KnownBox(*ref.single.server().SnapshotMap());
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));

  // Refused as by one server: a removed scan, a range without scans, an unknown sequence.
  EXPECT_TRUE(SameOutcome(b.client().CorrectPoses("r2", {{5, scans[0].pose}}),
                          single.CorrectPoses("r2", {{5, scans[0].pose}})));
  EXPECT_TRUE(SameOutcome(b.client().RemoveScans("r1", 50, 60), single.RemoveScans("r1", 50, 60)));
  EXPECT_TRUE(SameOutcome(a.client().CorrectPoses("r1", {{99, scans[0].pose}}),
                          single.CorrectPoses("r1", {{99, scans[0].pose}})));
  EXPECT_TRUE(SameCorrections(a.target(), ref.single.target()));
  EXPECT_TRUE(SameCorrections(b.target(), ref.single.target()));
  // The archive right after them: the affected tiles carry the corrections' versions.
  EXPECT_TRUE(SameExport(b.client(), single, dir, "corrected"));

  // Scans after the corrections, onto the corrected map.
  InsertByRobot(a.client(), b.client(), scans, most, scans.size());
  InsertAll(single, scans, most, scans.size());
  ref.box = KnownBox(*ref.single.server().SnapshotMap());
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));
  EXPECT_TRUE(SameExport(a.client(), single, dir, "after"));
  EXPECT_TRUE(SameCorrections(a.target(), ref.single.target()));
}

// A correction through b while the last scans stream in through a: the entry lands somewhere
// in the stream (the log grows while it is resolved, so its affected tiles grow over the new
// entries before it is appended). A single server fed the scans before the entry, the
// correction, then the rest exports the same bytes.
TEST(ClusterCorrectionTest, CorrectionWhileScansStreamIn) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = Drifted();
  const size_t most = scans.size() / 2;
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(a.client(), scans, 0, most);
  std::vector<uint64_t> versions;  // the streamed scans' log entries
  std::thread more([&] {
    for (size_t i = most; i < scans.size(); ++i) {
      RpcResult<ScanAck> ack = a.client().Insert(scans[i].Data());
      versions.push_back(ack.ok() ? ack->map_version : 0);
    }
  });
  RpcResult<CorrectionResult> corrected = b.client().CorrectPoses("r1", R1Poses(2, 5));
  more.join();
  ASSERT_TRUE(corrected.ok()) << corrected.status().message();
  const uint64_t at = corrected->map_version;
  size_t before = most;
  while (before < scans.size() && versions[before - most] != 0 && versions[before - most] < at) {
    ++before;
  }
  std::printf("the correction is entry %llu: after %zu of the %zu streamed scans\n",
              static_cast<unsigned long long>(at), before - most, scans.size() - most);
  ServerFixture single(StoreConfig(dir));
  InsertAll(single.client(), scans, 0, before);
  ASSERT_TRUE(single.client().CorrectPoses("r1", R1Poses(2, 5)).ok());
  InsertAll(single.client(), scans, before, scans.size());
  EXPECT_TRUE(SameExport(a.client(), single.client(), dir, "streamed"));
}

// Two bgkmapd shards; b killed with -9 just before a correction and a removal through a: the
// partitions b owned are taken over (from checkpoints), replay the log and are rebuilt at the
// entries; every answer is the single server's. `extra`: more shard settings.
void ExpectCorrectionsDuringATakeover(const std::vector<std::string>& extra) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = Drifted();
  Reference ref(scans, StoreConfig(dir));
  std::vector<std::string> args_a = NodeArgs(nats.urls(), "a"), args_b = NodeArgs(nats.urls(), "b");
  args_a.insert(args_a.end(), extra.begin(), extra.end());
  args_b.insert(args_b.end(), extra.begin(), extra.end());
  BgkmapdProcess a(args_a), b(args_b);
  ASSERT_TRUE(a.started() && b.started());
  Client to_a(a.target());
  InsertAll(to_a, scans, 0, scans.size());
  ASSERT_FALSE(b.WaitForLine("event=partition_checkpointed", 20).empty()) << "b wrote none";
  b.Signal(SIGKILL);
  Client& single = ref.single.client();
  EXPECT_TRUE(SameOutcome(to_a.CorrectPoses("r1", R1Poses(2, 9)),
                          single.CorrectPoses("r1", R1Poses(2, 9))));
  EXPECT_TRUE(SameOutcome(to_a.RemoveScans("r2", 3, 7), single.RemoveScans("r2", 3, 7)));
  EXPECT_TRUE(SameAnswers(to_a, ref));
  EXPECT_TRUE(SameExport(to_a, single, dir, "takeover"));
  EXPECT_TRUE(SameCorrections(a.target(), ref.single.target()));
  bool restored = false, rebuilt = false;
  for (const std::string& line : a.Log()) {
    restored = restored || (line.find("event=partition_taken") != std::string::npos &&
                            line.find("restored_from=0 ") == std::string::npos);
    rebuilt = rebuilt || line.find("event=partitions_rebuilt") != std::string::npos;
  }
  EXPECT_TRUE(restored) << "no partition was restored from a checkpoint";
  EXPECT_TRUE(rebuilt) << "no partition was rebuilt";
}

TEST(ClusterCorrectionTest, CorrectionsDuringATakeover) { ExpectCorrectionsDuringATakeover({}); }

// The same with the scans' payloads in streams per region (docs/scale-out.md): the correction
// reads and prepares the named scans from their region copies, the rebuilds replay them, and
// the survivor takes the killed shard's whole regions.
TEST(ClusterCorrectionTest, CorrectionsDuringATakeoverWithStreamsPerRegion) {
  ExpectCorrectionsDuringATakeover({"--set", "cluster.region_partitions=2"});
}

}  // namespace
}  // namespace bgkmap::testing
