// Ingest contract: duplicates are acked and not applied, a reconnecting robot continues, the
// unary form behaves like the stream, shutdown answers every scan read, and a stream that encodes
// on threads of its own (ClientOptions::ingest_encode_threads) acks exactly as one that does not.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <map>
#include <thread>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

std::vector<ScanData> DataOf(const std::vector<OwnedScan>& scans, size_t begin, size_t end) {
  std::vector<ScanData> out;
  for (size_t i = begin; i < end; ++i) out.push_back(scans[i].Data());
  return out;
}

TEST(IngestContractTest, DuplicatesAreNotDoubleCountedAndReconnectContinues) {
  const std::vector<OwnedScan> scans = SubScans("rover", 3);  // 9 scans
  ServerFixture fixture;
  // First connection: scans 1..5.
  RpcResult<std::vector<ScanAck>> first = fixture.client().IngestAll(DataOf(scans, 0, 5));
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  ASSERT_EQ(first->size(), 5u);  // an ack per scan, or the loop proves nothing
  for (const ScanAck& a : *first) EXPECT_EQ(a.status, AckStatus::kApplied);

  // The robot reconnects with a new client, resumes from what the server reports, and also
  // re-sends 3..5 whose acks it "lost".
  Client reconnected(fixture.target());
  RpcResult<std::optional<uint64_t>> last = reconnected.LastSequence("rover");
  ASSERT_TRUE(last.ok());
  ASSERT_TRUE(last->has_value());
  EXPECT_EQ(**last, 5u);
  RpcResult<std::vector<ScanAck>> second = reconnected.IngestAll(DataOf(scans, 2, 9));
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  ASSERT_EQ(second->size(), 7u);
  for (size_t i = 0; i < 7; ++i) {
    EXPECT_EQ((*second)[i].sequence, i + 3);
    EXPECT_EQ((*second)[i].status, i < 3 ? AckStatus::kDuplicate : AckStatus::kApplied);
    EXPECT_TRUE((*second)[i].error.ok());
  }
  // The unary form treats a retry the same way.
  RpcResult<ScanAck> retry = reconnected.Insert(scans[8].Data());
  ASSERT_TRUE(retry.ok()) << retry.status().ToString();
  EXPECT_EQ(retry->status, AckStatus::kDuplicate);
  EXPECT_EQ(retry->map_version, 9u);

  std::vector<const OwnedScan*> once;
  for (const OwnedScan& s : scans) once.push_back(&s);
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *OfflineMap(once)));
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->map_version, 9u);
  EXPECT_EQ(info->scans_applied, 9u);
  const RobotInfo* rover = info->FindRobot("rover");
  ASSERT_NE(rover, nullptr);
  EXPECT_EQ(rover->last_sequence, 9u);
  EXPECT_EQ(rover->scans_applied, 9u);
  EXPECT_EQ(rover->scans_duplicate, 4u);
}

TEST(IngestContractTest, UnaryInsertAppliesAndReportsCounts) {
  const std::vector<OwnedScan> scans = SubScans("unary", 8, 2);
  ServerFixture fixture;
  RpcResult<ScanAck> ack = fixture.client().Insert(scans[0].Data());
  ASSERT_TRUE(ack.ok()) << ack.status().ToString();
  EXPECT_EQ(ack->status, AckStatus::kApplied);
  EXPECT_EQ(ack->map_version, 1u);
  EXPECT_EQ(ack->counts.input, scans[0].points.size());
  const ScanPointCounts& c = ack->counts;
  EXPECT_EQ(
      c.kept + c.dropped_nonfinite + c.dropped_range + c.dropped_height + c.dropped_out_of_bounds,
      c.input);
  // A scan with no points (or none kept) is valid: it is applied and changes nothing.
  OwnedScan empty = scans[1];
  empty.points.clear();
  RpcResult<ScanAck> none = fixture.client().Insert(empty.Data());
  ASSERT_TRUE(none.ok()) << none.status().ToString();
  EXPECT_EQ(none->status, AckStatus::kApplied);
  EXPECT_EQ(none->map_version, 2u);
  EXPECT_TRUE(none->changed_tiles.empty());
}

TEST(IngestContractTest, WhenIngestFallsBehindFlowControlSlowsTheRobot) {
  // 120 full street scans (1.3 MB each): the robot can send far faster than they integrate.
  std::vector<ScanData> scans;
  for (uint64_t i = 0; i < 120; ++i) {
    ScanData d = StreetScans()[i % StreetScans().size()].Data();
    d.robot_id = "fast";
    d.sequence = i + 1;
    scans.push_back(d);
  }
  ServerConfig config = TestConfig();
  config.limits.max_inflight_scans_per_stream = 2;
  ServerFixture fixture(config);
  std::unique_ptr<IngestStream> stream = fixture.client().OpenIngest();
  std::atomic<size_t> sent{0};
  std::thread sender([&] {
    for (const ScanData& s : scans) {
      if (!stream->Send(s)) break;
      ++sent;
    }
    stream->CloseSend();
  });
  std::vector<ScanAck> acks;
  std::atomic<size_t> acked{0};
  std::thread reader([&] {
    ScanAck ack;
    while (stream->ReadAck(&ack)) {
      acks.push_back(ack);
      ++acked;
    }
  });
  // The server reads 2 scans ahead of its acks; what else the robot got out sits in gRPC's
  // flow-control windows (tens of MB with BDP probing), so the robot runs a bounded distance
  // ahead of the integration instead of sending everything.
  size_t max_ahead = 0;
  bool held_back = false;
  while (acked.load() < scans.size() && sent.load() < scans.size() + 1) {
    const size_t s = sent.load(), a = acked.load();
    max_ahead = std::max(max_ahead, s - std::min(s, a));
    held_back |= s < scans.size() && a > 0;
    if (s == scans.size()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  sender.join();
  reader.join();
  EXPECT_TRUE(stream->Finish().ok());
  EXPECT_TRUE(held_back);
  EXPECT_LT(max_ahead, scans.size() / 2) << "the robot ran far ahead of integration";
  ASSERT_EQ(acks.size(), scans.size());
  for (size_t i = 0; i < acks.size(); ++i) {
    EXPECT_EQ(acks[i].sequence, i + 1);
    EXPECT_EQ(acks[i].status, AckStatus::kApplied);
  }
}

TEST(IngestContractTest, AnEncodePipelineKeepsTheOrderAndReportsARejectedScanAsBefore) {
  // Scan 5 has a non-finite pose: rejected on its own, the stream goes on.
  std::vector<OwnedScan> scans = SubScans("pipe", 4, 12);
  scans[4].pose.tx = std::nan("");
  struct Run {
    std::vector<ScanAck> acks;
    std::unique_ptr<TerrainMap> map;
  };
  auto run = [&](int threads) {
    ServerFixture fixture;
    ClientOptions options;
    options.ingest_encode_threads = threads;
    options.ingest_encode_ahead = 3;
    Client client(fixture.target(), options);
    RpcResult<std::vector<ScanAck>> acks = client.IngestAll(DataOf(scans, 0, scans.size()));
    EXPECT_TRUE(acks.ok()) << acks.status().ToString();
    return Run{acks.ok() ? *acks : std::vector<ScanAck>(), fixture.server().SnapshotMap()};
  };
  const Run pipelined = run(3);
  const Run one_at_a_time = run(0);
  ASSERT_EQ(pipelined.acks.size(), scans.size());
  ASSERT_EQ(one_at_a_time.acks.size(), scans.size());
  for (size_t i = 0; i < scans.size(); ++i) {
    const ScanAck& a = pipelined.acks[i];
    const ScanAck& b = one_at_a_time.acks[i];
    EXPECT_EQ(a.sequence, i + 1);
    EXPECT_EQ(a.status, i == 4 ? AckStatus::kRejected : AckStatus::kApplied) << "scan " << i + 1;
    EXPECT_EQ(a.status, b.status);
    EXPECT_EQ(a.error.code(), b.error.code());
    EXPECT_EQ(a.error.message(), b.error.message());
    EXPECT_EQ(a.counts.input, b.counts.input);
    EXPECT_EQ(a.counts.kept, b.counts.kept);
  }
  EXPECT_EQ(pipelined.acks[4].error.code(), RpcCode::kInvalidArgument);
  EXPECT_NE(pipelined.acks[4].error.message().find("pose"), std::string::npos)
      << pipelined.acks[4].error.ToString();
  EXPECT_TRUE(MapsEqual(*pipelined.map, *one_at_a_time.map));
}

TEST(IngestContractTest, ShutdownAcksEveryScanReadAndTheMapHoldsExactlyTheAckedOnes) {
  const std::vector<OwnedScan> a = SubScans("a", 8);
  std::vector<OwnedScan> b = SubScans("b", 8);
  for (OwnedScan& s : b) s.pose.ty += 200;  // partly disjoint tiles
  ServerFixture fixture;
  std::unique_ptr<Client> second = fixture.NewClient();
  struct Run {
    std::vector<ScanAck> acks;
    RpcStatus end;
  };
  auto robot = [](Client& client, const std::vector<OwnedScan>& scans, Run* run) {
    std::unique_ptr<IngestStream> stream = client.OpenIngest();
    std::thread reader([&] {
      ScanAck ack;
      while (stream->ReadAck(&ack)) run->acks.push_back(ack);
    });
    for (const OwnedScan& s : scans) {
      if (!stream->Send(s.Data())) break;
    }
    stream->CloseSend();
    reader.join();
    run->end = stream->Finish();
  };
  Run ra, rb;
  std::thread ta([&] { robot(fixture.client(), a, &ra); });
  std::thread tb([&] { robot(*second, b, &rb); });
  // Stop while both stream: once 4 scans are in (polled, with a generous deadline for busy
  // machines rather than the 2 s it used to give up after).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (fixture.server().Report().scans_applied < 4 &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  fixture.server().Shutdown();
  ta.join();
  tb.join();

  std::map<uint64_t, const OwnedScan*> by_version;
  size_t applied = 0;
  const std::vector<OwnedScan>& b_const = b;
  for (auto [run, scans] : {std::pair{&ra, &a}, std::pair{&rb, &b_const}}) {
    // Acks are in order and contiguous from the first scan; UNAVAILABLE ends the stream.
    for (size_t i = 0; i < run->acks.size(); ++i) {
      const ScanAck& ack = run->acks[i];
      EXPECT_EQ(ack.sequence, i + 1);
      if (ack.status == AckStatus::kApplied) {
        ++applied;
        by_version[ack.map_version] = &(*scans)[i];
      } else {
        EXPECT_EQ(ack.error.code(), RpcCode::kUnavailable) << ack.error.ToString();
      }
    }
    if (run->acks.size() < scans->size()) {
      EXPECT_EQ(run->end.code(), RpcCode::kUnavailable) << run->end.ToString();
    }
  }
  EXPECT_GT(applied, 0u);
  const ServerReport report = fixture.server().Report();
  EXPECT_EQ(report.scans_applied, applied);
  EXPECT_EQ(report.map_version, applied);
  std::vector<const OwnedScan*> order;
  for (const auto& [v, s] : by_version) order.push_back(s);
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *OfflineMap(order)));
}

}  // namespace
}  // namespace bgkmap::testing
