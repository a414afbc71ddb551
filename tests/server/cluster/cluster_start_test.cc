// A shard started before its NATS cluster can answer (one server of three up: no JetStream quorum,
// no placement for a stream of three replicas) waits for it and says so, then joins once the
// servers are back; with a short
// cluster.startup_wait_s it gives up with one line naming the key. Real nats-server processes
// and real bgkmapd processes. Mutation caught: no wait (the first step's failure ends the start:
// the process exits before a second NATS server is up).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmapd_process.h"
#include "cluster_support.h"
#include "nats_cluster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

std::vector<std::string> ShardArgv(const std::string& nats, const std::string& node, int port,
                                   double startup_wait_s) {
  return {BGKMAPD_PATH,
          "--listen",
          "127.0.0.1:" + std::to_string(port),
          "--set",
          "cluster.node=" + node,
          "--set",
          "cluster.nats=" + nats,
          "--set",
          "cluster.replicas=3",
          "--set",
          "cluster.startup_wait_s=" + std::to_string(startup_wait_s),
          "--set",
          "cluster.key_file=" + TestClusterKeyFile()};
}

TEST(ClusterStartTest, AShardWaitsForJetStreamAndJoinsWhenItAnswers) {
  TempDir dir("bgkmap_cluster_start");
  NatsCluster nats(3, dir.str());
  ASSERT_TRUE(nats.started());
  nats.Kill(1);
  nats.Kill(2);  // one of three: JetStream has no quorum, no stream can be made

  const int port = FreeLoopbackPort();
  BgkmapdProcess shard(ShardArgv(nats.urls(), "a", port, 300),
                       "event=cluster_waiting_for_jetstream");
  ASSERT_FALSE(shard.FindLine("event=cluster_waiting_for_jetstream").empty())
      << "the shard did not say it waits";
  EXPECT_EQ(shard.Poll(), -1) << "the shard exited instead of waiting";

  // All three again (a stream of three replicas is placed only on three live servers).
  ASSERT_TRUE(nats.Restart(1));
  ASSERT_TRUE(nats.Restart(2));
  if (shard.WaitForLine("event=cluster_joined", 180).empty()) {
    for (const std::string& line : shard.Log()) std::fprintf(stderr, "%s\n", line.c_str());
    FAIL() << "the shard never joined";
  }
  ASSERT_FALSE(shard.WaitForLine("event=listening", 60).empty());
  Client client("127.0.0.1:" + std::to_string(port));
  EXPECT_TRUE(client.Info().ok());
}

TEST(ClusterStartTest, AShardGivesUpAfterStartupWaitNamingTheKey) {
  TempDir dir("bgkmap_cluster_start");
  NatsCluster nats(3, dir.str());
  ASSERT_TRUE(nats.started());
  nats.Kill(1);
  nats.Kill(2);
  BgkmapdProcess shard(ShardArgv(nats.urls(), "b", FreeLoopbackPort(), 1),
                       "event=cluster_waiting_for_jetstream");
  EXPECT_NE(shard.Wait(120), 0);
  EXPECT_FALSE(shard.FindLine("cluster.startup_wait_s").empty());
}

}  // namespace
}  // namespace bgkmap::testing
