// What the cluster tests share: a shard's config (in process) and arguments (a bgkmapd process),
// the cluster key they all use, the street's scans of two robots, and the single server they
// are compared with, bit for bit.
#pragma once

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/server/map_server.h"
#include "test_support.h"

namespace bgkmap::testing {

// A cluster key file (48 random bytes, mode 0600) shared by every shard of this test process, in
// a temporary directory removed at exit.
inline const std::string& TestClusterKeyFile() {
  static const TempDir dir("bgkmap_cluster_key");
  static const std::string path = [] {
    const std::string p = dir.Sub("cluster.key");
    std::random_device rd;
    std::string secret;
    for (int i = 0; i < 48; ++i) secret.push_back(static_cast<char>(rd() & 0xff));
    std::ofstream(p, std::ios::binary) << secret;
    chmod(p.c_str(), 0600);
    return p;
  }();
  return path;
}

inline constexpr uint32_t kPartitionTiles = 2;  // 12.8 m: the street spans dozens of partitions

inline ServerConfig NodeConfig(const std::string& nats, const std::string& node,
                               uint32_t replicas = 1, double lease_s = 1.0) {
  ServerConfig c = TestConfig();
  c.cluster.nats = nats;
  c.cluster.node = node;
  c.cluster.partition_tiles = kPartitionTiles;
  c.cluster.replicas = replicas;
  c.cluster.lease_s = lease_s;
  c.cluster.checkpoint_scans = 5;  // checkpoints are written during every test
  c.cluster.key_file = TestClusterKeyFile();
  return c;
}

inline std::vector<std::string> NodeArgs(const std::string& nats, const std::string& node) {
  return {"--set", "cluster.node=" + node,
          "--set", "cluster.nats=" + nats,
          "--set", "cluster.partition_tiles=" + std::to_string(kPartitionTiles),
          "--set", "cluster.lease_s=1",
          "--set", "cluster.checkpoint_scans=3",
          "--set", "server.worker_threads=1",
          "--set", "server.query_threads=1",
          "--set", "cluster.key_file=" + TestClusterKeyFile()};
}

// Two robots driving the street, interleaved: the order every map here receives them in.
inline std::vector<OwnedScan> TwoRobots() {
  std::vector<OwnedScan> a = SubScans("r1", 4), b = SubScans("r2", 4);
  std::vector<OwnedScan> out;
  for (size_t i = 0; i < std::max(a.size(), b.size()); ++i) {
    if (i < a.size()) out.push_back(a[i]);
    if (i < b.size()) out.push_back(b[i]);
  }
  return out;
}

inline ::testing::AssertionResult SameBits(const Raster& a, const Raster& b) {
  if (a.rows != b.rows || a.cols != b.cols || a.box != b.box || a.layers != b.layers) {
    return ::testing::AssertionFailure() << "different geometry or layers";
  }
  int64_t known = 0;
  for (size_t l = 0; l < a.data.size(); ++l) {
    for (size_t i = 0; i < a.data[l].size(); ++i) {
      if (std::memcmp(&a.data[l][i], &b.data[l][i], sizeof(float)) != 0) {
        return ::testing::AssertionFailure()
               << "layer " << l << " pixel " << i << ": " << a.data[l][i] << " vs " << b.data[l][i];
      }
      known += std::isfinite(a.data[l][i]) ? 1 : 0;
    }
  }
  if (known == 0) return ::testing::AssertionFailure() << "no known pixel";
  return ::testing::AssertionSuccess() << known << " known values";
}

inline void InsertAll(Client& client, const std::vector<OwnedScan>& scans, size_t from, size_t to) {
  for (size_t i = from; i < to; ++i) {
    RpcResult<ScanAck> ack = client.Insert(scans[i].Data());
    ASSERT_TRUE(ack.ok()) << ack.status().message();
    ASSERT_EQ(ack->status, AckStatus::kApplied) << i;
  }
}

// scans[from, to) in order, r1's through `a` and the other robots' through `b`: each applied.
inline void InsertByRobot(Client& a, Client& b, const std::vector<OwnedScan>& scans, size_t from,
                          size_t to) {
  for (size_t i = from; i < to; ++i) {
    Client& via = scans[i].robot_id == "r1" ? a : b;
    RpcResult<ScanAck> ack = via.Insert(scans[i].Data());
    ASSERT_TRUE(ack.ok()) << ack.status().message();
    ASSERT_EQ(ack->status, AckStatus::kApplied) << i;
  }
}

// The single server's answers, to compare with.
struct Reference {
  ServerFixture single;
  MetricBox box;
  explicit Reference(const std::vector<OwnedScan>& scans, const ServerConfig& config = TestConfig())
      : single(config) {
    InsertAll(single.client(), scans, 0, scans.size());
    box = KnownBox(*single.server().SnapshotMap());
  }
  Raster Region(const MetricBox& b, int stride) {
    return single.client().QueryRegion({b, {}, stride}).value();
  }
};

inline ::testing::AssertionResult SameAnswers(Client& node, Reference& ref) {
  // The whole street (dozens of partitions), coarse and fine; and a box inside one partition.
  const MetricBox inside{0.2, 0.2, 12.0, 12.0};
  for (auto [box, stride] : {std::pair{ref.box, 1}, std::pair{ref.box, 3}, std::pair{inside, 1}}) {
    RpcResult<Raster> got = node.QueryRegion({box, {}, stride});
    if (!got.ok()) return ::testing::AssertionFailure() << got.status().message();
    if (auto same = SameBits(*got, ref.Region(box, stride)); !same) return same;
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(ref.box.min_x, ref.box.max_x),
      y(ref.box.min_y, ref.box.max_y);
  std::vector<std::array<double, 2>> points(300);
  for (auto& p : points) p = {x(rng), y(rng)};
  RpcResult<PointValues> got = node.QueryPoints(points);
  RpcResult<PointValues> want = ref.single.client().QueryPoints(points);
  if (!got.ok() || !want.ok()) return ::testing::AssertionFailure() << "points query failed";
  if (got->values.size() != want->values.size() ||
      std::memcmp(got->values.data(), want->values.data(), got->values.size() * 4) != 0) {
    return ::testing::AssertionFailure() << "point values differ";
  }
  return ::testing::AssertionSuccess();
}

// How long a cluster may take to answer as one server again after a death (a JetStream election
// and the readers re-opened after it): a liveness bound, not a wait. Generous, because on CI's
// two loaded cores an election alone took 16 s and the whole recovery 27 s (a 30 s bound failed
// there); the tests print the time each recovery took.
inline constexpr std::chrono::seconds kRecoveryBound{120};

// SameAnswers, retried for kRecoveryBound from `since`: while JetStream elects new leaders after a
// NATS server's death, a query may find a partition unserved (UNAVAILABLE).
inline ::testing::AssertionResult EventuallySameAnswers(
    Client& node, Reference& ref, std::chrono::steady_clock::time_point since) {
  ::testing::AssertionResult same = SameAnswers(node, ref);
  while (!same && std::chrono::steady_clock::now() - since < kRecoveryBound) {
    same = SameAnswers(node, ref);
  }
  return same;
}

}  // namespace bgkmap::testing
