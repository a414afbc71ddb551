// Streams per region (cluster.region_partitions; docs/scale-out.md, "Streams per region") on a
// real nats-server: two shards fed two robots answer as one server bit for bit, the log holds
// the scans' order and headers but not their payloads (those are in the regions' streams), and
// no region is split between shards (each shard then needs only its own regions' payloads).
// Corrections, removals, an export and a takeover with streams per region:
// ClusterCorrectionTest.CorrectionsDuringATakeoverWithStreamsPerRegion.
//
// Mutations checked by hand (each makes the test fail):
//   - Membership::OwnerOf hashing the partition, not its region: regions split between shards;
//   - AppendScan keeping the payload in the log entry as well: the log holds the payloads.
#include <gtest/gtest.h>
#include <nats/nats.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/server/map_server.h"
#include "cluster/cluster_trust.h"
#include "cluster/region_streams.h"
#include "cluster_support.h"
#include "nats_cluster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

constexpr uint32_t kRegionPartitions = 2;  // regions of 4 x 4 tiles (25.6 m): several on the street

ServerConfig RegionNodeConfig(const std::string& nats, const std::string& node) {
  ServerConfig c = NodeConfig(nats, node);
  c.cluster.region_partitions = kRegionPartitions;
  return c;
}

struct StreamBytes {
  uint64_t log = 0;      // BGKMAP_LOG
  uint64_t regions = 0;  // every BGKMAP_REGION_* stream
  int region_streams = 0;
};

// What JetStream stores, asked with a client of the test's own.
StreamBytes ReadStreamBytes(const std::string& url) {
  StreamBytes out;
  natsConnection* nc = nullptr;
  jsCtx* js = nullptr;
  jsStreamInfoList* list = nullptr;
  if (natsConnection_ConnectTo(&nc, url.c_str()) == NATS_OK &&
      natsConnection_JetStream(&js, nc, nullptr) == NATS_OK &&
      js_Streams(&list, js, nullptr, nullptr) == NATS_OK) {
    for (int i = 0; i < list->Count; ++i) {
      const std::string name = list->List[i]->Config->Name;
      if (name == "BGKMAP_LOG") out.log = list->List[i]->State.Bytes;
      if (name.rfind("BGKMAP_REGION_", 0) == 0) {
        out.regions += list->List[i]->State.Bytes;
        ++out.region_streams;
      }
    }
  }
  jsStreamInfoList_Destroy(list);
  jsCtx_Destroy(js);
  natsConnection_Destroy(nc);
  return out;
}

// The regions of the partitions `info`'s shard serves ("x.y" names).
std::set<std::pair<int, int>> OwnedRegions(const MapInfo& info) {
  std::set<std::pair<int, int>> out;
  for (const ClusterPartitionInfo& p : info.cluster->owned) {
    int x = 0, y = 0;
    if (std::sscanf(p.name.c_str(), "%d.%d", &x, &y) != 2) continue;
    const cluster::RegionKey r = cluster::RegionOf({x, y}, kRegionPartitions);
    out.insert({r.x, r.y});
  }
  return out;
}

TEST(ClusterRegionTest, ShardsOwnWholeRegionsAndTheLogHoldsNoPayload) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  ServerFixture a(RegionNodeConfig(nats.urls(), "a")), b(RegionNodeConfig(nats.urls(), "b"));
  InsertByRobot(a.client(), b.client(), scans, 0, scans.size());
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));

  // The log keeps the order and the headers; the payloads are in the regions' streams.
  const StreamBytes stored = ReadStreamBytes(nats.url(0));
  std::printf("log %llu bytes, %d region streams %llu bytes\n",
              static_cast<unsigned long long>(stored.log), stored.region_streams,
              static_cast<unsigned long long>(stored.regions));
  EXPECT_GE(stored.region_streams, 2);
  EXPECT_LT(stored.log * 10, stored.regions);
  // A few hundred bytes of headers per entry (a scan here is ~75 kB).
  EXPECT_LT(stored.log, scans.size() * 4096);

  // No region is served by both shards once they have split them (a shard started a moment
  // before the other may hold a region for its grace period: wait for the split, not a time).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  std::set<std::pair<int, int>> ra, rb, shared;
  do {
    RpcResult<MapInfo> ia = a.client().Info(), ib = b.client().Info();
    ASSERT_TRUE(ia.ok() && ib.ok() && ia->cluster && ib->cluster);
    EXPECT_EQ(ia->cluster->region_partitions, kRegionPartitions);
    ra = OwnedRegions(*ia);
    rb = OwnedRegions(*ib);
    shared.clear();
    for (const auto& r : ra) {
      if (rb.count(r) != 0) shared.insert(r);
    }
    if (shared.empty() && ra.size() + rb.size() >= 2) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  } while (std::chrono::steady_clock::now() < deadline);
  EXPECT_TRUE(shared.empty()) << shared.size() << " regions served by both shards";
  EXPECT_GE(ra.size() + rb.size(), 2u);
  std::printf("regions: a %zu, b %zu\n", ra.size(), rb.size());
}

// Shards must agree on the regions (who owns what): one with other regions, or none, refuses to
// start with one line naming the setting (mutation: the setting not compared).
TEST(ClusterRegionTest, AShardWithOtherRegionsRefusesToStart) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  ServerFixture a(RegionNodeConfig(nats.urls(), "a"));
  for (uint32_t other : {0u, kRegionPartitions * 2}) {
    ServerConfig b = RegionNodeConfig(nats.urls(), "b");
    b.cluster.region_partitions = other;
    Result<std::unique_ptr<MapServer>> started = MapServer::Start(b);
    ASSERT_FALSE(started.ok()) << "region_partitions " << other;
    EXPECT_NE(started.status().message().find("cluster.region_partitions"), std::string::npos)
        << started.status().message();
  }
}

// A copy is believed only under the message id and digest its log entry names: a message that
// anyone else published on the region's subject, or the right message asked for with another
// digest, is DataLoss, never a payload (mutation: ReadCopy not checking the digest).
TEST(ClusterRegionTest, ACopyIsBelievedOnlyWithItsEntrysIdAndDigest) {
  TempDir dir("bgkmap_cluster");
  NatsCluster nats(1, dir.str());
  ASSERT_TRUE(nats.started());
  Result<std::unique_ptr<cluster::NatsClient>> client =
      cluster::NatsClient::Connect({nats.url(0)}, "region-test");
  ASSERT_TRUE(client.ok()) << client.status().message();
  cluster::RegionStreams regions(**client, {2, 1, 3600});
  const std::string payload = "the scan's bytes", digest = cluster::ClusterTrust::Digest(payload);
  // Partitions in two regions (region (0,0) is partitions -1..0 in x and y): a copy in each.
  Result<std::string> copies = regions.Store(payload, "r1/1", digest, {{0, 0}, {-1, -1}, {-2, 0}});
  ASSERT_TRUE(copies.ok()) << copies.status().message();
  EXPECT_EQ(*copies, "-1_0:1 0_0:1");
  // A retry stores nothing new and names the same copies.
  EXPECT_EQ(regions.Store(payload, "r1/1", digest, {{0, 0}, {-2, 0}}).value(), *copies);
  Result<std::string> read = cluster::ReadCopy(**client, *copies, "r1/1", digest, {{0, 0}});
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(*read, payload);
  // Another message on the region's subject (anyone's), named as the copy: not believed.
  natsConnection* nc = (*client)->connection();
  ASSERT_EQ(natsConnection_PublishString(nc, "bgkmap.region.0_0", "forged"), NATS_OK);
  ASSERT_EQ(natsConnection_Flush(nc), NATS_OK);
  EXPECT_EQ(cluster::ReadCopy(**client, "0_0:2", "r1/1", digest, std::nullopt).status().code(),
            Status::Code::kDataLoss);
  // The real copy asked for with another payload's digest: not believed either.
  const std::string other = cluster::ClusterTrust::Digest("other bytes");
  EXPECT_EQ(cluster::ReadCopy(**client, *copies, "r1/1", other, std::nullopt).status().code(),
            Status::Code::kDataLoss);
  // A message stored under the very id a copy would have, with other bytes: not believed.
  natsMsg* forged = nullptr;
  ASSERT_EQ(natsMsg_Create(&forged, "bgkmap.region.0_0", nullptr, "forged", 6), NATS_OK);
  const std::string id = cluster::CopyMessageId("r1/9", digest);
  natsMsgHeader_Set(forged, "Nats-Msg-Id", id.c_str());
  ASSERT_EQ(natsConnection_PublishMsg(nc, forged), NATS_OK);
  natsMsg_Destroy(forged);
  ASSERT_EQ(natsConnection_Flush(nc), NATS_OK);
  EXPECT_EQ(cluster::ReadCopy(**client, "0_0:3", "r1/9", digest, std::nullopt).status().code(),
            Status::Code::kDataLoss);
  // A copy the stream does not hold (purged, or never stored): DataLoss at once, not a wait.
  const auto asked = std::chrono::steady_clock::now();
  EXPECT_EQ(cluster::ReadCopy(**client, "0_0:99", "r1/1", digest, std::nullopt).status().code(),
            Status::Code::kDataLoss);
  EXPECT_LT(std::chrono::steady_clock::now() - asked, std::chrono::seconds(5));
  EXPECT_EQ(cluster::ReadCopy(**client, "0_0:x", "r1/1", digest, std::nullopt).status().code(),
            Status::Code::kDataLoss);
}

}  // namespace
}  // namespace bgkmap::testing
