// Concurrency contract: concurrent robots give the map of a sequential integration in
// acknowledgement (version) order, and readers never see part of a scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <set>
#include <thread>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

// Streams `scans` on one stream; returns the acks.
std::vector<ScanAck> Stream(Client& client, const std::vector<OwnedScan>& scans) {
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
  EXPECT_TRUE(acks.ok()) << acks.status().ToString();
  return acks.ok() ? *acks : std::vector<ScanAck>{};
}

// The scans in the order of the versions their acks report.
std::vector<const OwnedScan*> VersionOrder(
    const std::vector<std::pair<const std::vector<OwnedScan>*, std::vector<ScanAck>>>& runs) {
  std::map<uint64_t, const OwnedScan*> by_version;
  for (const auto& [scans, acks] : runs) {
    EXPECT_EQ(acks.size(), scans->size());
    for (size_t i = 0; i < acks.size() && i < scans->size(); ++i) {
      EXPECT_EQ(acks[i].status, AckStatus::kApplied) << acks[i].error.ToString();
      EXPECT_EQ(acks[i].sequence, (*scans)[i].sequence);
      EXPECT_TRUE(by_version.emplace(acks[i].map_version, &(*scans)[i]).second)
          << "version " << acks[i].map_version << " given twice";
    }
  }
  std::vector<const OwnedScan*> order;
  for (const auto& [v, s] : by_version) order.push_back(s);
  EXPECT_EQ(by_version.rbegin()->first, order.size());  // versions are 1..n
  return order;
}

std::vector<OwnedScan> Shifted(std::vector<OwnedScan> scans, double dx) {
  for (OwnedScan& s : scans) s.pose.tx += dx;
  return scans;
}

// Returns the peak number of scans integrating at once.
uint32_t RunTwoRobots(const std::vector<OwnedScan>& a, const std::vector<OwnedScan>& b) {
  ServerFixture fixture;
  std::unique_ptr<Client> second = fixture.NewClient();
  std::vector<ScanAck> acks_a, acks_b;
  std::thread ta([&] { acks_a = Stream(fixture.client(), a); });
  std::thread tb([&] { acks_b = Stream(*second, b); });
  ta.join();
  tb.join();
  const std::vector<const OwnedScan*> order = VersionOrder({{&a, acks_a}, {&b, acks_b}});
  EXPECT_EQ(order.size(), a.size() + b.size());
  // Both robots really interleaved.
  const auto first_b = std::find_if(order.begin(), order.end(),
                                    [](const OwnedScan* s) { return s->robot_id == "b"; });
  EXPECT_NE(first_b - order.begin(), static_cast<long>(a.size())) << "ran one after the other";
  std::unique_ptr<TerrainMap> sequential = OfflineMap(order);
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *sequential));
  const MetricBox box{-60, -60, 60, 60};
  RpcResult<Raster> served = fixture.client().QueryRegion({box, {}, 1});
  EXPECT_TRUE(served.ok()) << served.status().ToString();
  if (served.ok()) {
    EXPECT_TRUE(RastersMatch(*served, OfflineRegion(*sequential, box), 0.0));
  }
  return fixture.server().Report().peak_parallel_integrations;
}

// server.scan_bands: one robot's dense scans (the real Ouster street, ~30k observed cells each),
// each cut into bands that integrate on the workers beside each other, give the map of a
// sequential integration of the whole scans, and the same region answer.
TEST(ConcurrentIngestTest, ScansInBandsEqualSequentialIntegration) {
  ServerConfig config = TestConfig();
  config.scan_bands = 3;
  config.worker_threads = 3;
  ServerFixture fixture(config);
  const std::vector<OwnedScan>& scans = StreetScans();
  const std::vector<ScanAck> acks = Stream(fixture.client(), scans);
  const std::vector<const OwnedScan*> order = VersionOrder({{&scans, acks}});
  EXPECT_EQ(fixture.server().Report().banded_scans, scans.size()) << "a scan integrated whole";
  std::unique_ptr<TerrainMap> sequential = OfflineMap(order);
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *sequential));
  const MetricBox box{-60, -60, 60, 60};
  RpcResult<Raster> served = fixture.client().QueryRegion({box, {}, 1});
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  EXPECT_TRUE(RastersMatch(*served, OfflineRegion(*sequential, box), 0.0));
}

TEST(ConcurrentIngestTest, OverlappingRobotsEqualSequentialIntegrationInAckOrder) {
  // Every scan overlaps every other: none may ever integrate beside another.
  EXPECT_EQ(RunTwoRobots(SubScans("a", 5), SubScans("b", 4)), 1u);
}

TEST(ConcurrentIngestTest, DisjointRobotsEqualSequentialIntegration) {
  // Scans of the two robots share no tile: with two workers they integrate side by side.
  EXPECT_EQ(RunTwoRobots(SubScans("a", 4), Shifted(SubScans("b", 4), 1000.0)), 2u);
}

TEST(ConcurrentIngestTest, ReadersSeeEveryScanWholeOrNotAtAll) {
  const std::vector<OwnedScan> scans = SubScans("r", 4);
  const MetricBox box{-20, -20, 20, 20};
  ServerFixture fixture;
  std::unique_ptr<Client> reader = fixture.NewClient();
  std::atomic<bool> done{false};
  std::vector<std::pair<uint64_t, Raster>> seen;
  std::thread querier([&] {
    while (!done.load()) {
      uint64_t version = 0;
      RpcResult<Raster> r = reader->QueryRegion({box, {}, 1}, &version);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      seen.emplace_back(version, std::move(r).value());
    }
  });
  const std::vector<ScanAck> acks = Stream(fixture.client(), scans);
  done = true;
  querier.join();
  ASSERT_EQ(acks.size(), scans.size());
  ASSERT_GT(seen.size(), 3u);

  // Every state a reader may see: the map after the first k scans.
  std::vector<Raster> states;
  std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(MapParams{})).value();
  states.push_back(OfflineRegion(*map, box));
  for (const OwnedScan& s : scans) {
    ASSERT_TRUE(map->IntegrateScan(PointsAsIntegrated(s, MapParams{}), WirePose(s.pose)).ok());
    states.push_back(OfflineRegion(*map, box));
  }
  std::set<size_t> distinct;
  for (const auto& [version, raster] : seen) {
    size_t match = states.size();
    for (size_t k = version; k < states.size(); ++k) {
      if (RastersMatch(raster, states[k], 0.0)) {
        match = k;
        break;
      }
    }
    EXPECT_LT(match, states.size())
        << "a query at version " << version << " saw a state that no prefix of the scans produces";
    distinct.insert(match);
  }
  EXPECT_GT(distinct.size(), 1u) << "queries did not overlap ingestion";
}

}  // namespace
}  // namespace bgkmap::testing
