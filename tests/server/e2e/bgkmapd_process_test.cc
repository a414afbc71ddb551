// The bgkmapd binary: health checking and reflection answer, --print-config, SIGTERM while
// robots stream keeps every acknowledged scan (and nothing else) in the final map it reports, and
// a start with less free space than storage.min_free_space_mb (read-only, writes' health).
#include "bgkmapd_process.h"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <thread>

#include "bgkmap/client/client.h"
#include "bgkmap/io/kitti_sequence.h"
#include "health_probe.grpc.pb.h"
#include "reflection_probe.grpc.pb.h"

namespace bgkmap::testing {
namespace {

TEST(BgkmapdProcessTest, HealthCheckingAndReflectionAnswer) {
  BgkmapdProcess server;
  ASSERT_TRUE(server.started());
  {
    auto channel = grpc::CreateChannel(server.target(), grpc::InsecureChannelCredentials());

    auto health = grpc::health::v1::Health::NewStub(channel);
    for (const std::string service : {"", "bgkmap.v1.MapService"}) {
      grpc::ClientContext ctx;
      grpc::health::v1::HealthCheckRequest request;
      request.set_service(service);
      grpc::health::v1::HealthCheckResponse response;
      const grpc::Status s = health->Check(&ctx, request, &response);
      ASSERT_TRUE(s.ok()) << s.error_message();
      EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING) << service;
    }

    auto reflection = grpc::reflection::v1alpha::ServerReflection::NewStub(channel);
    grpc::ClientContext ctx;
    auto stream = reflection->ServerReflectionInfo(&ctx);
    grpc::reflection::v1alpha::ServerReflectionRequest request;
    request.set_list_services("*");
    ASSERT_TRUE(stream->Write(request));
    grpc::reflection::v1alpha::ServerReflectionResponse response;
    ASSERT_TRUE(stream->Read(&response));
    std::set<std::string> names;
    for (const auto& s : response.list_services_response().service()) names.insert(s.name());
    EXPECT_TRUE(names.count("bgkmap.v1.MapService"));
    EXPECT_TRUE(names.count("grpc.health.v1.Health"));
    // The service's schema is served too (what grpcurl needs).
    request.set_file_containing_symbol("bgkmap.v1.MapService");
    ASSERT_TRUE(stream->Write(request));
    ASSERT_TRUE(stream->Read(&response));
    EXPECT_GT(response.file_descriptor_response().file_descriptor_proto_size(), 0)
        << response.DebugString();
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  // The channel is closed first: an idle C++ client answers the server's graceful GOAWAY ping
  // only from its 5 s backup poller, which would just slow the test down.
  server.Signal(SIGINT);
  EXPECT_EQ(server.Wait(), 0);
}

TEST(BgkmapdProcessTest, PrintConfigShowsFileAndFlagOverrides) {
  const std::string path = ::testing::TempDir() + "/bgkmapd_test.yaml";
  std::ofstream(path) << "resolution: 0.2\nserver:\n  max_robots: 12\n  worker_threads: 1\n";
  const auto [code, out] = RunBgkmapd(
      {"--config", path, "--worker-threads", "3", "--set", "kernel_length=0.5", "--print-config"});
  EXPECT_EQ(code, 0);
  EXPECT_NE(out.find("resolution: 0.2"), std::string::npos) << out;
  EXPECT_NE(out.find("kernel_length: 0.5"), std::string::npos) << out;
  EXPECT_NE(out.find("max_robots: 12"), std::string::npos) << out;
  EXPECT_NE(out.find("worker_threads: 3"), std::string::npos) << out;
  EXPECT_EQ(RunBgkmapd({"--set", "server.bogus=1", "--print-config"}).first, 2);
}

// String flags are values, not YAML: an IPv6 address or a path with '#' or ': ' stays whole.
TEST(BgkmapdProcessTest, StringFlagsAreTakenLiterally) {
  const auto [code, out] =
      RunBgkmapd({"--listen", "[::1]:50999", "--data-dir", "/tmp/maps #1: site", "--print-config"});
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("[::1]:50999"), std::string::npos) << out;
  EXPECT_NE(out.find("/tmp/maps #1: site"), std::string::npos) << out;
}

// `acks` is written by the stream's reader thread and read by the test only after that thread
// has been joined; while it runs, the test reads the count only, which is atomic. (It used to
// read acks.size() while the reader pushed: a data race in the test itself.)
struct RobotRun {
  std::vector<ScanAck> acks;
  std::atomic<size_t> acked{0};  // acks.size(), published after each push
  RpcStatus end;
};

// Streams sub-scans of the street sequence as `robot` until the stream ends.
void StreamUntilStopped(const std::string& target, const std::string& robot, double dx,
                        RobotRun* run) {
  Result<io::KittiSequence> seq =
      io::KittiSequence::Open(std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street");
  ASSERT_TRUE(seq.ok());
  struct Part {
    std::vector<Point3f> points;
    ScanPose pose;
  };
  std::vector<Part> parts;
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> scan = seq->Read(k);
    ASSERT_TRUE(scan.ok());
    for (int p = 0; p < 10; ++p) {
      Part part;
      part.pose = ScanPose::FromPose(scan->pose);
      part.pose.tx += dx;
      for (size_t i = static_cast<size_t>(p); i < scan->points.size(); i += 10) {
        part.points.push_back(scan->points[i]);
      }
      parts.push_back(std::move(part));
    }
  }
  Client client(target);
  std::unique_ptr<IngestStream> stream = client.OpenIngest();
  std::thread reader([&] {
    ScanAck ack;
    while (stream->ReadAck(&ack)) {
      run->acks.push_back(ack);
      run->acked.store(run->acks.size(), std::memory_order_release);
    }
  });
  // Loops over the parts with increasing sequence numbers until the server stops.
  for (uint64_t seqno = 1; seqno < 100000; ++seqno) {
    const Part& part = parts[(seqno - 1) % parts.size()];
    ScanData d;
    d.robot_id = robot;
    d.sequence = seqno;
    d.pose = part.pose;
    d.points = part.points;
    if (!stream->Send(d)) break;
  }
  reader.join();
  run->end = stream->Finish();
}

TEST(BgkmapdProcessTest, SigtermWhileRobotsStreamKeepsEveryAcknowledgedScan) {
  BgkmapdProcess server({"--worker-threads", "2"});
  ASSERT_TRUE(server.started());
  RobotRun a, b;
  std::thread ta([&] { StreamUntilStopped(server.target(), "alpha", 0.0, &a); });
  std::thread tb([&] { StreamUntilStopped(server.target(), "beta", 150.0, &b); });
  // Let both robots get some scans in, then stop the server under load. A generous deadline:
  // on 2 busy cores the first acks can take seconds.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(90);
  while ((a.acked.load(std::memory_order_acquire) < 3 ||
          b.acked.load(std::memory_order_acquire) < 3) &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  server.Signal(SIGTERM);
  ta.join();
  tb.join();
  ASSERT_EQ(server.Wait(), 0);

  const std::string final_line = server.FindLine("event=final_map");
  ASSERT_FALSE(final_line.empty());
  std::smatch m;
  ASSERT_TRUE(std::regex_search(final_line, m, std::regex("scans_applied=([0-9]+)")));
  const uint64_t server_applied = std::stoull(m[1]);
  ASSERT_TRUE(std::regex_search(final_line, m, std::regex("robots=(\\S*)")));
  std::map<std::string, uint64_t> last;
  const std::string robots = m[1];
  const std::regex entry("([a-z]+):([0-9]+)");
  for (auto it = std::sregex_iterator(robots.begin(), robots.end(), entry);
       it != std::sregex_iterator(); ++it) {
    last[(*it)[1]] = std::stoull((*it)[2]);
  }

  uint64_t acked_applied = 0;
  for (auto [name, run] : {std::pair{"alpha", &a}, std::pair{"beta", &b}}) {
    ASSERT_GE(run->acks.size(), 3u) << name;
    uint64_t last_applied = 0;
    for (size_t i = 0; i < run->acks.size(); ++i) {
      EXPECT_EQ(run->acks[i].sequence, i + 1) << name;  // every scan read is answered, in order
      if (run->acks[i].status == AckStatus::kApplied) {
        ++acked_applied;
        last_applied = run->acks[i].sequence;
      } else {
        EXPECT_EQ(run->acks[i].error.code(), RpcCode::kUnavailable);
      }
    }
    EXPECT_EQ(run->end.code(), RpcCode::kUnavailable) << run->end.ToString();
    EXPECT_EQ(last[name], last_applied) << name;  // the map holds up to the last acked scan
  }
  // Every acknowledged scan is in the final map, and no unacknowledged one.
  EXPECT_EQ(server_applied, acked_applied);
  EXPECT_FALSE(server.FindLine("event=shutdown_done").empty());
}

grpc::health::v1::HealthCheckResponse::ServingStatus Health(const std::string& target,
                                                            const std::string& service) {
  auto channel = grpc::CreateChannel(target, grpc::InsecureChannelCredentials());
  auto health = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext ctx;
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status s = health->Check(&ctx, request, &response);
  EXPECT_TRUE(s.ok()) << service << ": " << s.error_message();
  return response.status();
}

// No small file system needed: a reserve larger than any disk (2^30 MB) is a full disk to the
// server. (RealDiskFullTest does it on a real full tmpfs.)
TEST(BgkmapdProcessTest, AStartBelowTheFreeSpaceReserveServesReadsOnly) {
  const std::string dir = ::testing::TempDir() + "/bgkmapd_reserve_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  Result<io::KittiSequence> seq =
      io::KittiSequence::Open(std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street");
  ASSERT_TRUE(seq.ok());
  Result<io::Scan> scan = seq->Read(0);
  ASSERT_TRUE(scan.ok());
  ScanData d;
  d.robot_id = "alpha";
  d.sequence = 1;
  d.pose = ScanPose::FromPose(scan->pose);
  d.points = scan->points;
  {
    BgkmapdProcess server({"--data-dir", dir, "--set", "storage.min_free_space_mb=0"});
    ASSERT_TRUE(server.started());
    EXPECT_EQ(Health(server.target(), "bgkmap.v1.MapService/writes"),
              grpc::health::v1::HealthCheckResponse::SERVING);
    Client client(server.target());
    ASSERT_TRUE(client.Insert(d).ok());
    server.Signal(SIGKILL);  // the scan is in the log only: the next start replays it
    server.Wait();
  }
  BgkmapdProcess server({"--data-dir", dir, "--set", "storage.min_free_space_mb=1073741824"});
  ASSERT_TRUE(server.started());
  const std::string why = server.FindLine("event=storage_read_only");
  EXPECT_NE(why.find("below the reserve of 1073741824.0 MB"), std::string::npos) << why;
  for (const std::string service : {"", "bgkmap.v1.MapService"}) {
    EXPECT_EQ(Health(server.target(), service), grpc::health::v1::HealthCheckResponse::SERVING)
        << service;
  }
  EXPECT_EQ(Health(server.target(), "bgkmap.v1.MapService/writes"),
            grpc::health::v1::HealthCheckResponse::NOT_SERVING);
  Client client(server.target());
  RpcResult<MapInfo> info = client.Info();
  ASSERT_TRUE(info.ok());
  ASSERT_TRUE(info->storage.has_value());
  EXPECT_TRUE(info->storage->read_only);
  EXPECT_TRUE(info->storage->writes_paused_for_space);
  EXPECT_EQ(info->map_version, 1u);
  EXPECT_GT(info->known_cells, 0u);  // the replayed scan, from memory
  ASSERT_NE(info->FindRobot("alpha"), nullptr);
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, 1u);
  const std::vector<std::array<double, 2>> points = {{2, 0}};
  RpcResult<PointValues> values = client.QueryPoints(points, {Layer::kElevation});
  ASSERT_TRUE(values.ok()) << values.status().ToString();
  d.sequence = 2;
  RpcResult<ScanAck> refused = client.Insert(d);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), RpcCode::kUnavailable);
  EXPECT_NE(refused.status().message().find("read-only"), std::string::npos)
      << refused.status().message();
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(), 0);
  std::filesystem::remove_all(dir);
}

// Issue 25, finding 3: gRPC sets SO_REUSEPORT by default, so a second bgkmapd on the same address
// started, said "listening" and took part of the calls (an empty map answering). The listener
// is exclusive: the second start fails with one line naming the address, the first serves on.
// Mutation caught: dropping the GRPC_ARG_ALLOW_REUSEPORT=0 argument in ListenGrpc (the second
// process then logs event=listening and keeps running).
TEST(BgkmapdProcessTest, ASecondServerOnTheSameGrpcAddressIsRefusedAtStart) {
  BgkmapdProcess first;
  ASSERT_TRUE(first.started());
  BgkmapdProcess second({BGKMAPD_PATH, "--listen", first.target()},
                        "event=(?:listening|start_failed)");
  EXPECT_EQ(second.Wait(30), 1) << "the second server did not exit";
  const std::string failed = second.FindLine("event=start_failed");
  EXPECT_NE(failed.find(first.target()), std::string::npos) << failed;
  EXPECT_NE(failed.find("in use"), std::string::npos) << failed;
  EXPECT_TRUE(second.FindLine("event=listening").empty());
  EXPECT_EQ(Health(first.target(), "bgkmap.v1.MapService"),
            grpc::health::v1::HealthCheckResponse::SERVING);
  first.Signal(SIGTERM);
  EXPECT_EQ(first.Wait(), 0);
}

}  // namespace
}  // namespace bgkmap::testing
