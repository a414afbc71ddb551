// A bgkmap cluster on real nats-server processes (JetStream) against a single server fed the
// same scans in the same order: the answers must be the same bits, inside one partition and
// across partitions, after duplicates and retries, after a shard is killed (its partitions are
// taken over) and while a NATS server is down and after it catches up.
//
// Mutations checked by hand (each makes a test below fail):
//   - PartitionLayout's halo without the kernel's second reach (2 l -> l): region answers differ
//     at partition borders (AnswersEqualSingleServer);
//   - ClusterReads fetching without min_log_sequence (0): a query right after ingest misses
//     scans (AnswersEqualSingleServer);
//   - the replica applying a duplicate robot sequence: RetriesAndDuplicatesChangeNothing.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "bgkmap/client/client.h"
#include "bgkmap/server/map_server.h"
#include "bgkmap/storage/map_archive.h"
#include "bgkmapd_process.h"
#include "cluster_support.h"
#include "loopback_http.h"
#include "nats_cluster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

// Two shards fed two robots' scans, r1 through a and r2 through b, one at a time (the log's
// order is the reference's), answer right away (no waiting: a query reads at least every
// acknowledged scan) as one server of the same method does, and Info on either counts what the
// single server's Info counts (mutation: a partition's owner counting its halo's tiles too).
// Before anyone asks Info, a's /metrics comes to count the cluster's known cells as well (a
// scrape refreshes the counts in the background and shows the previous refresh's).
void ExpectTwoShardsAnswerAsOne(Method method) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  ServerConfig single = TestConfig();
  ServerConfig ca = NodeConfig(nats.urls(), "a"), cb = NodeConfig(nats.urls(), "b");
  single.map.method = ca.map.method = cb.map.method = method;
  ca.metrics_address = "127.0.0.1:0";
  Reference ref(scans, single);
  ServerFixture a(ca), b(cb);
  InsertByRobot(a.client(), b.client(), scans, 0, scans.size());
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));
  const MapInfo want = ref.single.client().Info().value();
  const auto known = static_cast<int64_t>(want.known_cells);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  int64_t scraped = MetricsSample(a.server().http_port(), "bgkmap_map_known_cells");
  while (scraped != known && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    scraped = MetricsSample(a.server().http_port(), "bgkmap_map_known_cells");
  }
  EXPECT_EQ(scraped, known) << "a's /metrics without an Info";
  // Info on either shard counts the whole cluster as the single server counts its map.
  for (Client* via : {&a.client(), &b.client()}) {
    RpcResult<MapInfo> got = via->Info();
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->tile_count, want.tile_count);
    EXPECT_EQ(got->known_cells, want.known_cells);
    EXPECT_EQ(got->known_cells_box, want.known_cells_box);
    EXPECT_EQ(got->known_bounds.min_x, want.known_bounds.min_x);
    EXPECT_EQ(got->known_bounds.max_y, want.known_bounds.max_y);
    EXPECT_EQ(got->scans_applied, want.scans_applied);
    ASSERT_EQ(got->robots.size(), want.robots.size());
    for (size_t i = 0; i < want.robots.size(); ++i) {
      EXPECT_EQ(got->robots[i].robot_id, want.robots[i].robot_id);
      EXPECT_EQ(got->robots[i].last_sequence, want.robots[i].last_sequence);
      EXPECT_EQ(got->robots[i].scans_applied, want.robots[i].scans_applied);
    }
  }
}

TEST(ClusterTest, AnswersEqualSingleServer) { ExpectTwoShardsAnswerAsOne(Method::kBgkPlus); }

// bgk-ll's plane moments through the cluster: the log, each shard's partitions with their halos,
// checkpoints and the tile fetches of a query on any node answer as one bgk-ll server does.
TEST(ClusterTest, BgkLlAnswersEqualSingleServer) {
  ExpectTwoShardsAnswerAsOne(Method::kBgkLocalLinear);
}

// Mutation: a shard clearing only its own partition's cells, not its halo's copies (the
// traversability of later scans near the partition's edge differs).
TEST(ClusterTest, ClearsAreOrderedWithTheScans) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  const size_t half = scans.size() / 2;
  // A box across four partitions (12.8 m) and their halos, cleared between the halves.
  const MetricBox box{-6.0, -6.0, 7.0, 7.0};
  ServerFixture single;
  InsertAll(single.client(), scans, 0, half);
  ASSERT_TRUE(single.client().ClearRegion(box).ok());
  InsertAll(single.client(), scans, half, scans.size());
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(a.client(), scans, 0, half);
  RpcResult<ClearResult> cleared = b.client().ClearRegion(box);
  ASSERT_TRUE(cleared.ok()) << cleared.status().message();
  EXPECT_EQ(cleared->map_version, half + 1);  // the log's sequence of the clear
  InsertAll(b.client(), scans, half, scans.size());
  const MetricBox street = KnownBox(*single.server().SnapshotMap());
  for (Client* via : {&a.client(), &b.client()}) {
    RpcResult<Raster> got = via->QueryRegion({street, {}, 1});
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_TRUE(SameBits(*got, single.client().QueryRegion({street, {}, 1}).value()));
  }
}

// An archive of one map imported (merged) into the cluster between scans, as into a single
// server. Mutation: a shard adding only the tiles of its own partition, not its halo's (the
// traversability of later scans near the partition's edge differs).
TEST(ClusterTest, ImportsAreOrderedWithTheScans) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  const size_t half = scans.size() / 2;
  // The archive: another robot's map of the street.
  const std::string archive = dir.Sub("other.bgkmap");
  {
    ServerFixture other;
    const std::vector<OwnedScan> r3 = SubScans("r3", 3);
    InsertAll(other.client(), r3, 0, r3.size());
    ASSERT_TRUE(other.client().ExportMap(std::nullopt, archive).ok());
  }
  ServerFixture single;
  InsertAll(single.client(), scans, 0, half);
  ASSERT_TRUE(single.client().ImportMap(archive).ok());
  InsertAll(single.client(), scans, half, scans.size());
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(a.client(), scans, 0, half);
  RpcResult<ImportResult> imported = b.client().ImportMap(archive);
  ASSERT_TRUE(imported.ok()) << imported.status().message();
  EXPECT_EQ(imported->map_version, half + 1);  // one entry of the log
  InsertAll(b.client(), scans, half, scans.size());
  const MetricBox street = KnownBox(*single.server().SnapshotMap());
  for (Client* via : {&a.client(), &b.client()}) {
    RpcResult<Raster> got = via->QueryRegion({street, {}, 1});
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_TRUE(SameBits(*got, single.client().QueryRegion({street, {}, 1}).value()));
  }
}

TEST(ClusterTest, RetriesAndDuplicatesChangeNothing) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(a.client(), scans, 0, scans.size());
  // Every scan again, through the other node (a robot retrying after a failover): stored once.
  for (const OwnedScan& s : scans) {
    RpcResult<ScanAck> ack = b.client().Insert(s.Data());
    ASSERT_TRUE(ack.ok()) << ack.status().message();
    EXPECT_EQ(ack->status, AckStatus::kDuplicate);
  }
  EXPECT_TRUE(SameAnswers(b.client(), ref));
}

// Info on a shard names it and sees the scans its own acks reported. (Through the map port:
// ReadVersion.) Every call is taken on a shard: CorrectPoses and RemoveScans are tested in
// cluster_correction_test.cc.
TEST(ClusterTest, InfoOnAShardNamesIt) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  ServerFixture a(NodeConfig(nats.urls(), "a"));
  const std::vector<OwnedScan> scans = SubScans("r1", 4, 2);
  uint64_t acked = 0;
  for (const OwnedScan& s : scans) {
    RpcResult<ScanAck> ack = a.client().Insert(s.Data());
    ASSERT_TRUE(ack.ok()) << ack.status().message();
    ASSERT_EQ(ack->status, AckStatus::kApplied);
    acked = ack->map_version;
  }
  RpcResult<MapInfo> info = a.client().Info();
  ASSERT_TRUE(info.ok()) << info.status().message();
  ASSERT_TRUE(info->cluster.has_value());
  EXPECT_EQ(info->cluster->node, "a");
  EXPECT_EQ(info->cluster->partition_tiles, kPartitionTiles);
  EXPECT_GE(info->map_version, acked);
}

// Mutations: ReadCheckpoint returning nothing (the takeover replays the log: "no partition was
// restored"); the restored replica dropping the checkpoint's tiles (the answers differ).
TEST(ClusterTest, KilledShardsPartitionsAreServedAgain) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  BgkmapdProcess a(NodeArgs(nats.urls(), "a")), b(NodeArgs(nats.urls(), "b"));
  ASSERT_TRUE(a.started() && b.started());
  Client to_a(a.target());
  const size_t half = scans.size() / 2;
  InsertAll(to_a, scans, 0, half);
  ASSERT_FALSE(b.WaitForLine("event=partition_serving", 10).empty()) << "b never served";
  if (b.WaitForLine("event=partition_checkpointed", 10).empty()) {
    for (const std::string& line : b.Log()) std::fprintf(stderr, "b: %s\n", line.c_str());
    FAIL() << "b wrote no checkpoint";
  }
  b.Signal(SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  // Ingest goes on through the survivor; every acknowledged scan must be in its answers.
  InsertAll(to_a, scans, half, scans.size());
  EXPECT_TRUE(SameAnswers(to_a, ref));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  // A bound against a takeover that stalls, generous for a loaded machine (it includes inserting
  // the second half and the comparison); the takeover's own time is measured in scale-out.md.
  EXPECT_LT(seconds, 60.0) << "b's partitions took " << seconds << " s to be served again";
  // b's partitions came back from their checkpoints, not from the log's start.
  bool restored = false;
  for (const std::string& line : a.Log()) {
    restored = restored || (line.find("event=partition_taken") != std::string::npos &&
                            line.find("restored_from=0 ") == std::string::npos);
  }
  EXPECT_TRUE(restored) << "no partition was restored from a checkpoint";
  // The robots retry what they sent before the failover, through the survivor: stored once,
  // nothing changes.
  for (size_t i = 0; i < half; ++i) {
    RpcResult<ScanAck> ack = to_a.Insert(scans[i].Data());
    ASSERT_TRUE(ack.ok()) << ack.status().message();
    EXPECT_EQ(ack->status, AckStatus::kDuplicate) << i;
  }
  EXPECT_TRUE(SameAnswers(to_a, ref));
  std::printf("takeover: every partition answered %.2f s after kill -9\n", seconds);
}

// The log trimmed below the partitions' checkpoints (cluster.trim_lag_entries): a shard killed
// afterwards has its partitions restored from checkpoints and the log's rest, and a shard that
// joins afterwards too; the answers stay the single server's. CorrectPoses and RemoveScans are
// refused (FAILED_PRECONDITION: they need the whole log). Mutations: the floor taken as the
// log's end, ignoring the checkpoints (scans after the first trim are in no checkpoint yet: the
// takeover misses them and the answers differ); no checkpoint by lag (nothing is trimmed).
TEST(ClusterTest, TrimmedLogLosesNothing) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  auto args = [&](const std::string& node) {
    std::vector<std::string> a = NodeArgs(nats.urls(), node);
    // Checkpoints by lag only: the second half below (4 entries) writes none.
    a.insert(a.end(),
             {"--set", "cluster.trim_lag_entries=6", "--set", "cluster.checkpoint_scans=1000"});
    return a;
  };
  BgkmapdProcess a(args("a")), b(args("b"));
  ASSERT_TRUE(a.started() && b.started());
  Client to_a(a.target());
  ASSERT_FALSE(b.WaitForLine("event=cluster_joined", 10).empty());
  const size_t half = scans.size() / 2;
  InsertAll(to_a, scans, 0, half);
  // Entries that change nothing (clears of a place without data), so that every partition's
  // newest checkpoint falls behind by the lag and is written again.
  std::string trimmed;
  for (int i = 0; i < 40 && trimmed.empty(); ++i) {
    ASSERT_TRUE(to_a.ClearRegion({5000, 5000, 5001, 5001}).ok());
    trimmed = a.FindLine("event=cluster_log_trimmed");
    if (trimmed.empty()) trimmed = b.FindLine("event=cluster_log_trimmed");
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  ASSERT_FALSE(trimmed.empty()) << "the log was never trimmed";
  EXPECT_EQ(trimmed.find("kept_from=1 "), std::string::npos) << trimmed;
  // The rest, and time for more trims (every 4 leases): entries no checkpoint holds yet stay.
  InsertAll(to_a, scans, half, scans.size());
  std::this_thread::sleep_for(std::chrono::seconds(5));
  // Corrections replay the log from its start: refused on a log that is trimmed, naming the
  // setting that keeps it (the map unchanged: the answers below).
  for (const RpcStatus& refused : {to_a.CorrectPoses("r1", {{2, scans[0].pose}}).status(),
                                   to_a.RemoveScans("r2", 1, 3).status()}) {
    EXPECT_EQ(refused.code(), RpcCode::kFailedPrecondition) << refused.message();
    EXPECT_NE(refused.message().find("cluster.trim_lag_entries"), std::string::npos)
        << refused.message();
  }
  EXPECT_TRUE(SameAnswers(to_a, ref));

  b.Signal(SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  EXPECT_TRUE(EventuallySameAnswers(to_a, ref, killed));
  BgkmapdProcess c(args("c"));
  ASSERT_TRUE(c.started());
  Client to_c(c.target());
  ASSERT_FALSE(c.WaitForLine("event=partition_serving", 15).empty()) << "c took nothing";
  EXPECT_TRUE(EventuallySameAnswers(to_c, ref, std::chrono::steady_clock::now()));
  EXPECT_TRUE(EventuallySameAnswers(to_a, ref, std::chrono::steady_clock::now()));
  // c's robot ledger started on the trimmed log from a checkpoint's robot table: it knows the
  // robots as the single server does (mutation: a ledger reading the trimmed log from its first
  // entry knows fewer scans of them).
  RpcResult<MapInfo> info = to_c.Info();
  ASSERT_TRUE(info.ok()) << info.status().message();
  const MapInfo want = ref.single.client().Info().value();
  ASSERT_EQ(info->robots.size(), want.robots.size());
  for (size_t i = 0; i < want.robots.size(); ++i) {
    EXPECT_EQ(info->robots[i].robot_id, want.robots[i].robot_id);
    EXPECT_EQ(info->robots[i].last_sequence, want.robots[i].last_sequence);
  }
  EXPECT_FALSE(c.FindLine("event=robot_ledger_seeded").empty());
  std::printf("%s\n", trimmed.c_str());
}

TEST(ClusterTest, SurvivesANatsServerAndItCatchesUp) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(3, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  // A lease of 3 s (the default) outlasts a JetStream leader election.
  ServerFixture a(NodeConfig(nats.urls(), "a", 3, 3.0)), b(NodeConfig(nats.urls(), "b", 3, 3.0));
  const size_t half = scans.size() / 2;
  InsertAll(a.client(), scans, 0, half);
  nats.Kill(0);
  const auto killed = std::chrono::steady_clock::now();
  // Two of three remain: the log and the buckets keep their quorum. Appends wait out the
  // election; a query may find a partition unserved while its reader is re-created (UNAVAILABLE,
  // retried here up to kRecoveryBound).
  InsertAll(b.client(), scans, half, scans.size());
  EXPECT_TRUE(EventuallySameAnswers(a.client(), ref, killed));
  std::printf("NATS server killed: answers equal again after %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count());
  // n0 comes back and catches up; with n1 down, the quorum needs it.
  ASSERT_TRUE(nats.Restart(0));
  ASSERT_TRUE(nats.WaitCaughtUp(0, kRecoveryBound.count())) << "n0 never caught up";
  nats.Kill(1);
  const auto killed_again = std::chrono::steady_clock::now();
  EXPECT_TRUE(EventuallySameAnswers(b.client(), ref, killed_again));
  std::printf(
      "a second NATS server killed: answers equal again after %.1f s\n",
      std::chrono::duration<double>(std::chrono::steady_clock::now() - killed_again).count());
}

// The newest update of each tile a Watch sent.
class LatestTiles {
 public:
  void Add(const TileUpdate& u) {
    std::lock_guard lock(mu_);
    Raster& r = latest_[u.key];
    if (r.data.empty() || u.map_version >= versions_[u.key]) {
      r = u.raster;
      versions_[u.key] = u.map_version;
    }
  }
  std::map<TileKey, Raster> Get() const {
    std::lock_guard lock(mu_);
    return latest_;
  }
  // Tiles whose latest update has a known elevation (layer 0). A shard also sends tiles of a
  // change's box that hold nothing (its log tells it the box a scan can change, not the tiles it
  // did); their state layer says "unknown" with a finite code, so only elevation tells them.
  std::set<TileKey> KnownKeys() const {
    std::lock_guard lock(mu_);
    std::set<TileKey> out;
    for (const auto& [key, r] : latest_) {
      if (!r.data.empty() && std::any_of(r.data[0].begin(), r.data[0].end(),
                                         [](float v) { return std::isfinite(v); })) {
        out.insert(key);
      }
    }
    return out;
  }

 private:
  mutable std::mutex mu_;
  std::map<TileKey, Raster> latest_;
  std::map<TileKey, uint64_t> versions_;
};

// Every tile of `want` with a known cell arrived, and every update holds `want`'s values.
::testing::AssertionResult WatchedEquals(const std::map<TileKey, Raster>& got, const Raster& want,
                                         const GridGeometry& g) {
  std::set<TileKey> known_tiles;
  for (int64_t row = 0; row < want.rows; ++row) {
    for (int64_t col = 0; col < want.cols; ++col) {
      if (std::isfinite(want.data[0][row * want.cols + col])) {
        known_tiles.insert(g.TileOf(
            {want.box.min.x + static_cast<int>(col), want.box.max.y - static_cast<int>(row)}));
      }
    }
  }
  for (TileKey k : known_tiles) {
    if (!got.contains(k)) {
      return ::testing::AssertionFailure() << "tile " << k.x << "," << k.y << " never sent";
    }
  }
  int64_t compared = 0;
  for (const auto& [key, r] : got) {
    if (r.layers != want.layers) return ::testing::AssertionFailure() << "layers differ";
    for (int64_t row = 0; row < r.rows; ++row) {
      for (int64_t col = 0; col < r.cols; ++col) {
        const CellIndex c{r.box.min.x + static_cast<int>(col), r.box.max.y - static_cast<int>(row)};
        for (size_t l = 0; l < r.layers.size(); ++l) {
          const float v = r.data[l][row * r.cols + col];
          if (!want.box.Contains(c)) {
            return ::testing::AssertionFailure()
                   << "tile " << key.x << "," << key.y << " is not watched";
          }
          const float w = want.data[l][(want.box.max.y - c.y) * want.cols + (c.x - want.box.min.x)];
          if (std::memcmp(&v, &w, sizeof v) != 0) {
            return ::testing::AssertionFailure()
                   << "tile " << key.x << "," << key.y << " cell " << c.x << "," << c.y << " layer "
                   << l << ": " << v << " vs " << w;
          }
          compared += std::isfinite(w) ? 1 : 0;
        }
      }
    }
  }
  return ::testing::AssertionSuccess() << compared << " known values";
}

// A Watch on a shard that owns none of what changes, started mid-ingest with a first snapshot,
// across dozens of partitions, through scans and a clear sent to the other shard: the newest
// update of every tile is the single server's tile, bit for bit. Mutations: the log's changed
// cells header left out of scan entries (tiles stay stale); the first snapshot not listed.
TEST(ClusterTest, WatchOnAnyShardSeesEveryChange) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  const size_t half = scans.size() / 2;
  const MetricBox cleared{-6.0, -6.0, 7.0, 7.0};
  ServerFixture single;
  InsertAll(single.client(), scans, 0, half);
  std::set<TileKey> tiles_at_half;
  single.server().SnapshotMap()->ForEachTile(
      [&](TileKey key, const Tile&) { tiles_at_half.insert(key); });
  ASSERT_TRUE(single.client().ClearRegion(cleared).ok());
  InsertAll(single.client(), scans, half, scans.size());
  const MetricBox street = KnownBox(*single.server().SnapshotMap());
  const GridGeometry g = single.server().SnapshotMap()->geometry();
  // The whole tiles the watch covers (cell centres, so no cell beyond them).
  const CellBox tiles{g.TileBox(g.TileOf(g.CellAt(street.min_x, street.min_y))).min,
                      g.TileBox(g.TileOf(g.CellAt(street.max_x, street.max_y))).max};
  const double res = g.resolution();
  const MetricBox whole{(tiles.min.x + 0.5) * res, (tiles.min.y + 0.5) * res,
                        (tiles.max.x + 0.5) * res, (tiles.max.y + 0.5) * res};
  const Raster want = single.client().QueryRegion({whole, {}, 1}).value();

  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(b.client(), scans, 0, half);
  LatestTiles latest;
  std::unique_ptr<WatchSubscription> watch = a.client().Watch(
      {street, {}, /*initial_snapshot=*/true}, [&](const TileUpdate& u) { latest.Add(u); });
  // The first snapshot has arrived before the map changes again: what follows must be told.
  const auto started = std::chrono::steady_clock::now();
  // (Every tile of the map at half, by elevation: found by CI and again under load, where shard
  // a's change feed was still reading the first half's entries when the watch subscribed and
  // their boxes' empty tiles came too; counted by any finite layer, they made 154 of 152.)
  auto snapshot_arrived = [&] {
    const std::set<TileKey> known = latest.KnownKeys();
    return std::includes(known.begin(), known.end(), tiles_at_half.begin(), tiles_at_half.end());
  };
  while (!snapshot_arrived() && std::chrono::steady_clock::now() - started < kRecoveryBound) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(snapshot_arrived()) << "the first snapshot: " << latest.KnownKeys().size() << " of "
                                  << tiles_at_half.size() << " tiles";
  RpcResult<ClearResult> clear = b.client().ClearRegion(cleared);
  ASSERT_TRUE(clear.ok()) << clear.status().message();
  InsertAll(b.client(), scans, half, scans.size());
  const auto since = std::chrono::steady_clock::now();
  ::testing::AssertionResult same = WatchedEquals(latest.Get(), want, g);
  while (!same && std::chrono::steady_clock::now() - since < kRecoveryBound) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    same = WatchedEquals(latest.Get(), want, g);
  }
  EXPECT_TRUE(same);
  watch->Cancel();
  EXPECT_EQ(watch->Wait().code(), RpcCode::kCancelled);
}

// What a client hears of one step, in words both a single server and a shard must say alike.
std::string Heard(const RpcResult<ScanAck>& ack) {
  if (!ack.ok()) return "refused " + std::to_string(static_cast<int>(ack.status().code()));
  return ack->status == AckStatus::kApplied     ? "applied"
         : ack->status == AckStatus::kDuplicate ? "duplicate"
                                                : "other";
}
std::string Heard(const RpcResult<RetiredRobot>& retired) {
  if (!retired.ok()) return "refused " + std::to_string(static_cast<int>(retired.status().code()));
  return "retired last=" + std::to_string(retired->last_sequence) +
         " robots=" + std::to_string(retired->robots);
}

// server.max_robots = 2 and server.max_sequence_jump = 100 on a single server and on two shards,
// and RetireRobot through either shard, interleaved with three robots' scans: every answer
// (applied, duplicate, the refusal's code, the retired robot's last sequence and the robots
// left) and the map are the single server's. After r2's retirement its sequence starts again at
// 1: those scans are applied again, not taken for retries of its old ones. Mutations: replicas
// without the limits (a refused scan integrated: the regions differ); the ledger not forgetting
// a retired robot (r3 refused as one robot too many); the message id without the epoch (r2's
// new scan 1 answered as a duplicate).
TEST(ClusterTest, RobotLimitsAndRetirementAsOneServer) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  ServerConfig single = TestConfig();
  ServerConfig ca = NodeConfig(nats.urls(), "a"), cb = NodeConfig(nats.urls(), "b");
  for (ServerConfig* c : {&single, &ca, &cb}) {
    c->limits.max_robots = 2;
    c->limits.max_sequence_jump = 100;
  }
  ServerFixture one(single), a(ca), b(cb);
  const std::vector<OwnedScan> r1 = SubScans("r1", 4), r2 = SubScans("r2", 4),
                               r3 = SubScans("r3", 4);
  OwnedScan jump = r1[7];
  jump.sequence = 5000;  // more than 100 above r1's last
  std::vector<std::string> want, got;
  auto scan = [&](Client& via, const OwnedScan& s) {
    want.push_back(s.robot_id + "/" + std::to_string(s.sequence) + " " +
                   Heard(one.client().Insert(s.Data())));
    got.push_back(s.robot_id + "/" + std::to_string(s.sequence) + " " +
                  Heard(via.Insert(s.Data())));
  };
  auto retire = [&](Client& via, const std::string& robot) {
    want.push_back("retire " + robot + " " + Heard(one.client().RetireRobot(robot)));
    got.push_back("retire " + robot + " " + Heard(via.RetireRobot(robot)));
  };
  for (size_t i = 0; i < 6; ++i) {
    scan(a.client(), r1[i]);
    scan(b.client(), r2[i]);
  }
  scan(a.client(), r3[0]);       // a third robot: RESOURCE_EXHAUSTED
  scan(b.client(), jump);        // OUT_OF_RANGE
  scan(a.client(), r1[6]);       // applied: the jump changed nothing
  retire(a.client(), "r2");      // last 6, one robot left
  retire(b.client(), "nobody");  // NOT_FOUND
  for (size_t i = 0; i < 6; ++i) scan(b.client(), r3[i]);
  scan(a.client(), r2[6]);  // r2 is new again: one robot too many
  retire(b.client(), "r3");
  for (size_t i = 0; i < 4; ++i) scan(a.client(), r2[i]);  // r2 from 1 again: applied
  scan(b.client(), r2[2]);                                 // a retry: duplicate
  EXPECT_EQ(got, want);
  const MetricBox street = KnownBox(*one.server().SnapshotMap());
  for (Client* via : {&a.client(), &b.client()}) {
    RpcResult<Raster> region = via->QueryRegion({street, {}, 1});
    ASSERT_TRUE(region.ok()) << region.status().message();
    EXPECT_TRUE(SameBits(*region, one.client().QueryRegion({street, {}, 1}).value()));
    RpcResult<MapInfo> info = via->Info();
    ASSERT_TRUE(info.ok()) << info.status().message();
    std::vector<std::pair<std::string, uint64_t>> robots, single_robots;
    for (const RobotInfo& r : info->robots) robots.emplace_back(r.robot_id, r.last_sequence);
    const MapInfo single_info = one.client().Info().value();
    for (const RobotInfo& r : single_info.robots) {
      single_robots.emplace_back(r.robot_id, r.last_sequence);
    }
    EXPECT_EQ(robots, single_robots);
  }
}

// An archive with finite extreme statistics imported twice through two shards: the second
// import is refused as a single server refuses it (OUT_OF_RANGE, the same message naming the
// tile and cell), and the map is the single server's. Mutation: the shard without
// CheckImportSums (the second import is stored and the partitions' sums overflow).
TEST(ClusterTest, ImportWhoseSumsWouldOverflowIsRefusedAsByOneServer) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  ServerConfig single = TestConfig();
  ServerConfig ca = NodeConfig(nats.urls(), "a"), cb = NodeConfig(nats.urls(), "b");
  for (ServerConfig* c : {&single, &ca, &cb}) c->map.dynamics = Dynamics::kOff;
  const std::string archive = dir.Sub("extreme.bgkmap");
  {
    storage::MapMetadata meta;
    meta.params = single.map;
    Result<std::unique_ptr<storage::MapArchiveWriter>> w =
        storage::MapArchiveWriter::Create(archive, meta);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    Tile tile(single.map.tile_size);
    tile.w()[0] = 1e308;  // finite, possible; twice is not
    tile.s()[0] = 1e308;
    tile.a()[0] = 3e38f;
    tile.b()[0] = 3e38f;
    tile.w()[1] = 1.0;
    tile.s()[1] = 0.5;
    ASSERT_TRUE((*w)->Add({0, 0}, tile).ok());
    ASSERT_TRUE((*w)->Finish().ok());
  }
  ServerFixture one(single), a(ca), b(cb);
  ASSERT_TRUE(one.client().ImportMap(archive).ok());
  RpcResult<ImportResult> first = a.client().ImportMap(archive);
  ASSERT_TRUE(first.ok()) << first.status().message();
  RpcResult<ImportResult> want = one.client().ImportMap(archive);
  RpcResult<ImportResult> got = b.client().ImportMap(archive);
  ASSERT_FALSE(want.ok());
  ASSERT_FALSE(got.ok()) << "the sums overflow to inf";
  EXPECT_EQ(got.status().code(), RpcCode::kOutOfRange) << got.status().message();
  EXPECT_EQ(got.status().message(), want.status().message());
  const MetricBox box{0.05, 0.05, 6.35, 6.35};  // tile (0, 0)
  for (Client* via : {&a.client(), &b.client()}) {
    RpcResult<Raster> region = via->QueryRegion({box, {}, 1});
    ASSERT_TRUE(region.ok()) << region.status().message();
    EXPECT_TRUE(SameBits(*region, one.client().QueryRegion({box, {}, 1}).value()));
  }
}

// The bytes of a file (an exported archive).
std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Whether two archives are the same bytes, else their sizes and the first offset that differs.
::testing::AssertionResult SameFile(const std::string& a, const std::string& b) {
  const std::string x = FileBytes(a), y = FileBytes(b);
  if (x == y && !x.empty()) return ::testing::AssertionSuccess();
  size_t i = 0;
  while (i < x.size() && i < y.size() && x[i] == y[i]) ++i;
  return ::testing::AssertionFailure() << a << " (" << x.size() << " bytes) and " << b << " ("
                                       << y.size() << " bytes) differ from byte " << i;
}

// ExportMap through either shard, of the whole map and of a box across partitions, is the single
// server's archive of the same scans byte for byte (header, versions, tiles in key order,
// trailer); an export taken while scans stream in through the other shard holds exactly the
// scans before its entry in the log (a single server fed those exports the same bytes).
// Mutations (the first run failed so): the archive's version and its tiles' versions left as log
// sequences (the export entries before the last export shift them: the bytes differ).
TEST(ClusterTest, ExportsEqualSingleServerByteForByte) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  const size_t half = scans.size() / 2;
  ServerFixture single;
  InsertAll(single.client(), scans, 0, half);
  const MetricBox box{-6.0, -6.0, 7.0, 7.0};
  ASSERT_TRUE(single.client().ExportMap(std::nullopt, dir.Sub("single.bgkmap")).ok());
  ASSERT_TRUE(single.client().ExportMap(box, dir.Sub("single-box.bgkmap")).ok());
  ServerFixture a(NodeConfig(nats.urls(), "a")), b(NodeConfig(nats.urls(), "b"));
  InsertAll(a.client(), scans, 0, half);
  // The rest of the scans stream in through a while b exports.
  std::thread more([&] { InsertAll(a.client(), scans, half, scans.size()); });
  RpcResult<ExportResult> whole = b.client().ExportMap(std::nullopt, dir.Sub("whole.bgkmap"));
  more.join();
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  RpcResult<ExportResult> boxed = a.client().ExportMap(box, dir.Sub("box.bgkmap"));
  ASSERT_TRUE(boxed.ok()) << boxed.status().message();
  InsertAll(single.client(), scans, half, scans.size());
  ASSERT_TRUE(single.client().ExportMap(box, dir.Sub("single-box-all.bgkmap")).ok());
  EXPECT_TRUE(SameFile(dir.Sub("box.bgkmap"), dir.Sub("single-box-all.bgkmap")));
  ASSERT_TRUE(single.client().ExportMap(std::nullopt, dir.Sub("single-all.bgkmap")).ok());
  RpcResult<ExportResult> all = b.client().ExportMap(std::nullopt, dir.Sub("all.bgkmap"));
  ASSERT_TRUE(all.ok()) << all.status().message();
  EXPECT_TRUE(SameFile(dir.Sub("all.bgkmap"), dir.Sub("single-all.bgkmap")));
  // The export during ingest holds exactly the scans before its entry: its version says how many,
  // and a single server fed those exports the same bytes.
  Result<std::unique_ptr<storage::MapArchiveReader>> during =
      storage::MapArchiveReader::Open(dir.Sub("whole.bgkmap"));
  ASSERT_TRUE(during.ok()) << during.status().ToString();
  const uint64_t k = (*during)->metadata().map_version;
  ASSERT_GE(k, half);
  ASSERT_LE(k, scans.size());
  ServerFixture prefix;
  InsertAll(prefix.client(), scans, 0, k);
  ASSERT_TRUE(prefix.client().ExportMap(std::nullopt, dir.Sub("prefix.bgkmap")).ok());
  EXPECT_TRUE(SameFile(dir.Sub("whole.bgkmap"), dir.Sub("prefix.bgkmap"))) << k << " scans";
  std::printf("the export during ingest holds %llu of %zu scans\n",
              static_cast<unsigned long long>(k), scans.size());
}

// A shard killed with -9, then an export and a retirement through the survivor while it takes
// the dead shard's partitions over (from their checkpoints, replaying the log through the
// export's entry): the archive is the single server's byte for byte, and r2's scans sent again
// from 1 after its retirement are applied as a single server applies them.
TEST(ClusterTest, ExportAndRetirementDuringATakeover) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  ServerFixture single;
  InsertAll(single.client(), scans, 0, scans.size());
  ASSERT_TRUE(single.client().ExportMap(std::nullopt, dir.Sub("single.bgkmap")).ok());
  BgkmapdProcess a(NodeArgs(nats.urls(), "a")), b(NodeArgs(nats.urls(), "b"));
  ASSERT_TRUE(a.started() && b.started());
  Client to_a(a.target());
  InsertAll(to_a, scans, 0, scans.size());
  ASSERT_FALSE(b.WaitForLine("event=partition_checkpointed", 20).empty()) << "b wrote none";
  b.Signal(SIGKILL);
  RpcResult<ExportResult> exported = to_a.ExportMap(std::nullopt, dir.Sub("shard.bgkmap"));
  ASSERT_TRUE(exported.ok()) << exported.status().message();
  EXPECT_TRUE(SameFile(dir.Sub("shard.bgkmap"), dir.Sub("single.bgkmap")));
  // b's partitions were taken over from their checkpoints, not from the log's start.
  bool restored = false;
  for (const std::string& line : a.Log()) {
    restored = restored || (line.find("event=partition_taken") != std::string::npos &&
                            line.find("restored_from=0 ") == std::string::npos);
  }
  EXPECT_TRUE(restored) << "no partition was restored from a checkpoint";
  RpcResult<RetiredRobot> retired = to_a.RetireRobot("r2");
  RpcResult<RetiredRobot> want = single.client().RetireRobot("r2");
  ASSERT_TRUE(retired.ok() && want.ok()) << retired.status().message();
  EXPECT_EQ(retired->last_sequence, want->last_sequence);
  EXPECT_EQ(retired->robots, want->robots);
  std::vector<OwnedScan> again = SubScans("r2", 4);
  again.resize(3);
  InsertAll(single.client(), again, 0, again.size());
  InsertAll(to_a, again, 0, again.size());
  const MetricBox street = KnownBox(*single.server().SnapshotMap());
  RpcResult<Raster> got = to_a.QueryRegion({street, {}, 1});
  ASSERT_TRUE(got.ok()) << got.status().message();
  EXPECT_TRUE(SameBits(*got, single.client().QueryRegion({street, {}, 1}).value()));
}

}  // namespace
}  // namespace bgkmap::testing
