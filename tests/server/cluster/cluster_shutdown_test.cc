// A shard's parts stopped while work is still aimed at them, on a real nats-server (the cluster's
// shutdown contract, cluster/cluster_node.h).
//
// A partition replica stopped while tile fetches wait for it: a shard releases a partition (a
// rebalance) or leaves (its destructor) while other nodes' queries are queued at the replica.
// nats.c runs the fetch handler on its own thread, one message at a time, each waiting up to 2 s
// for log entries the replica will never read now. Before the fix the replica waited at most 5 s
// for nats.c's drain and was then freed with fetches still queued: the next one ran on the freed
// replica (ASan: heap-use-after-free in ServeFetch; without ASan a crash or a reply from freed
// memory).
//
// A node destroyed while a task it posted to its executor (ReadVersion, an export) has not run
// yet: before the fix the node was freed under it.
#include <gtest/gtest.h>
#include <nats/nats.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "bgkmap/v1/cluster.pb.h"
#include "cluster/cluster_node.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"
#include "cluster/partition_replica.h"
#include "cluster_support.h"
#include "nats_cluster.h"
#include "test_support.h"

namespace bgkmap::cluster {
namespace {

using testing::NatsCluster;
using testing::TempDir;

constexpr int kQueuedFetches = 6;  // 6 x 2 s of waiting: longer than any bounded drain wait

TEST(ClusterShutdownTest, AReplicaStopAnswersEveryQueuedFetchAndOutlivesThem) {
  TempDir dir("bgkmap_cluster_shutdown");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  Result<std::unique_ptr<NatsClient>> owner = NatsClient::Connect({nats.url(0)}, "owner");
  Result<std::unique_ptr<NatsClient>> asker = NatsClient::Connect({nats.url(0)}, "asker");
  ASSERT_TRUE(owner.ok() && asker.ok());
  const std::unique_ptr<ClusterTrust> trust = ClusterTrust::Insecure();
  const MapParams params = testing::TestConfig().map;
  const PartitionLayout layout(params, 2);
  const PartitionKey key{0, 0};
  // Serving at once (it has read the log's end as of its start: nothing), never fed an entry.
  auto replica = std::make_unique<PartitionReplica>(**owner, *trust, layout, key,
                                                    TerrainMap::Create(params).value(),
                                                    /*serve_from=*/0, RobotSequenceRule{});
  ASSERT_EQ(natsConnection_Flush((*owner)->connection()), NATS_OK);  // the server knows its queue

  natsSubscription* raw = nullptr;
  natsConnection* nc = (*asker)->connection();
  ASSERT_EQ(natsConnection_SubscribeSync(&raw, nc, "test.replies.*"), NATS_OK);
  NatsPtr<natsSubscription> replies(raw);
  ASSERT_EQ(natsConnection_Flush(nc), NATS_OK);
  v1::TileFetchRequest request;
  request.set_min_log_sequence(1000);  // an entry the replica will not read
  const std::string bytes = request.SerializeAsString();
  for (int i = 0; i < kQueuedFetches; ++i) {
    ASSERT_EQ(natsConnection_PublishRequest(nc, ("bgkmap.tiles." + PartitionName(key)).c_str(),
                                            ("test.replies." + std::to_string(i)).c_str(),
                                            bytes.data(), static_cast<int>(bytes.size())),
              NATS_OK);
  }
  ASSERT_EQ(natsConnection_Flush(nc), NATS_OK);
  // The first answer (after its 2 s wait) says the handler runs and the others are queued.
  natsMsg* first = nullptr;
  ASSERT_EQ(natsSubscription_NextMsg(&first, replies.get(), 30000), NATS_OK);
  NatsPtr<natsMsg> first_owned(first);

  const auto t0 = std::chrono::steady_clock::now();
  replica.reset();
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Every reply the replica sent reaches the asker's queue before the round trips below end
  // (the server forwards in order).
  ASSERT_EQ(natsConnection_Flush((*owner)->connection()), NATS_OK);
  ASSERT_EQ(natsConnection_Flush(nc), NATS_OK);
  int pending = 0;
  ASSERT_EQ(natsSubscription_GetPending(replies.get(), &pending, nullptr), NATS_OK);
  // Each queued fetch was answered before the replica was gone (a refusal: it is leaving),
  // none after; and the stop did not wait out the fetches' waits for the log.
  EXPECT_EQ(pending + 1, kQueuedFetches);
  EXPECT_LT(stop_s, 2.0);
}

TEST(ClusterShutdownTest, ANodeOutlivesTheTasksItPosted) {
  TempDir dir("bgkmap_cluster_shutdown");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const ClusterConfig config = testing::NodeConfig(nats.url(0), "a").cluster;
  // An executor that runs nothing until told: the task is still queued when the node goes.
  std::mutex mu;
  std::deque<std::function<void()>> queued;
  auto executor = [&](std::function<void()> task) {
    std::lock_guard lock(mu);
    queued.push_back(std::move(task));
  };
  auto no_scans = [](const v1::Scan&, const Pose*, PreparedScan*) {
    return Status::InvalidArgument("none");
  };
  const MapParams params = testing::TestConfig().map;
  Result<std::unique_ptr<ClusterNode>> node = ClusterNode::Start(
      config, params, "params", no_scans, Georeference{}, executor, RobotSequenceRule{});
  ASSERT_TRUE(node.ok()) << node.status().message();
  std::promise<uint64_t> version;
  (*node)->ReadVersion([&](uint64_t v) { version.set_value(v); });
  std::function<void()> task;
  {
    std::lock_guard lock(mu);
    ASSERT_EQ(queued.size(), 1u);
    task = std::move(queued.front());
    queued.clear();
  }
  auto destroyed = std::async(std::launch::async, [&] { node->reset(); });
  // The node waits for its task (before the fix it was gone within milliseconds); a slow
  // machine can only hide the bug here, never fail a correct node.
  EXPECT_EQ(destroyed.wait_for(std::chrono::seconds(3)), std::future_status::timeout);
  task();          // reads the log and the partitions' owners through the node: it must be whole
  task = nullptr;  // the executor is done with it
  EXPECT_EQ(version.get_future().get(), 0u);  // an empty log
  destroyed.get();
}

// A shard leaves while its NATS server holds the connection but answers nothing (stopped, as
// an overloaded server looks): every wait of its shutdown is bounded (drains, joins, the
// connection's close), so the process can exit.
TEST(ClusterShutdownTest, ANodeLeavesWhileNatsDoesNotAnswer) {
  TempDir dir("bgkmap_cluster_shutdown");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  auto a = std::make_unique<testing::ServerFixture>(testing::NodeConfig(nats.url(0), "a"));
  const std::vector<testing::OwnedScan> scans = testing::TwoRobots();
  testing::InsertAll(a->client(), scans, 0, 4);
  // Its partitions served (a query gathers them from their owner, this node).
  const auto asked = std::chrono::steady_clock::now();
  RpcResult<Raster> region = a->client().QueryRegion({{-20, -20, 20, 20}, {}, 1});
  while (!region.ok() && std::chrono::steady_clock::now() - asked < testing::kRecoveryBound) {
    region = a->client().QueryRegion({{-20, -20, 20, 20}, {}, 1});
  }
  ASSERT_TRUE(region.ok()) << region.status().message();
  nats.Signal(0, SIGSTOP);
  const auto t0 = std::chrono::steady_clock::now();
  a.reset();
  const double leave_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  nats.Signal(0, SIGCONT);
  std::fprintf(stderr, "left in %.1f s with NATS stopped\n", leave_s);
  EXPECT_LT(leave_s, 60.0);
}

}  // namespace
}  // namespace bgkmap::cluster
