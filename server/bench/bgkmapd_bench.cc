// End-to-end benchmark of bgkmapd over loopback: ingest throughput with 1, 4 and 16 robots
// streaming VLP-16 scans of the simulated city, region query latency (50 x 50 m and
// 200 x 200 m, all layers) and 1,000-point query latency while 4 robots stream.
// Usage: bgkmapd_bench [scans_per_robot=40]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/server/heap_policy.h"
#include "bgkmap/server/map_server.h"
#include "bgkmap/sim/city_world.h"
#include "bgkmap/sim/ray_caster.h"
#include "bgkmap/sim/scenario.h"

namespace {

using Clock = std::chrono::steady_clock;
using bgkmap::Client;
using bgkmap::ScanData;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

struct SimScan {
  std::vector<bgkmap::Point3f> points;
  bgkmap::ScanPose pose;
};

std::vector<SimScan> SimulateCity(size_t n) {
  const bgkmap::sim::Scenario city = bgkmap::sim::MakeCityScenario(210.0, 1.0, 10.0);
  std::vector<SimScan> scans;
  for (size_t i = 0; i < n && i < city.mapping_poses.size(); ++i) {
    SimScan s;
    s.points = bgkmap::sim::SimulateScan(*city.world, city.beams, city.mapping_poses[i]);
    s.pose = bgkmap::ScanPose::FromPose(city.mapping_poses[i]);
    scans.push_back(std::move(s));
  }
  return scans;
}

// Robot r drives the city shifted 60 m east per robot; streams `count` scans (looping) from
// sequence `first`, or until `stop` is set when count == 0.
size_t RunRobot(const std::string& target, int r, const std::vector<SimScan>& scans, size_t count,
                const std::atomic<bool>* stop, uint64_t* points, double rate_hz = 0) {
  Client client(target);
  auto stream = client.OpenIngest();
  size_t acked = 0;
  std::thread reader([&] {
    bgkmap::ScanAck ack;
    while (stream->ReadAck(&ack)) {
      ++acked;
      *points += ack.counts.input;
    }
  });
  const auto start = Clock::now();
  for (size_t i = 0; count == 0 ? !stop->load() : i < count; ++i) {
    const SimScan& s = scans[i % scans.size()];
    ScanData d;
    d.robot_id = "robot" + std::to_string(r);
    d.sequence = i + 1;
    d.pose = s.pose;
    d.pose.tx += 60.0 * r;
    d.points = s.points;
    if (!stream->Send(d)) break;
    if (rate_hz > 0) {
      std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                                std::chrono::duration<double>((i + 1) / rate_hz)));
    }
  }
  stream->CloseSend();
  reader.join();
  stream->Finish();
  return acked;
}

double Percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5))];
}

// Ingest throughput with 1, 4 and 16 robots streaming `per_robot` scans each, one server each.
void BenchIngest(const std::vector<SimScan>& scans, size_t per_robot) {
  std::printf("| robots | scans | seconds | scans/s | points/s |\n|---|---|---|---|---|\n");
  for (int robots : {1, 4, 16}) {
    bgkmap::ServerConfig config;
    config.listen_address = "127.0.0.1:0";
    auto server = std::move(bgkmap::MapServer::Start(config)).value();
    const std::string target = "127.0.0.1:" + std::to_string(server->port());
    std::vector<std::thread> threads;
    std::vector<uint64_t> points(robots, 0);
    std::vector<size_t> acked(robots, 0);
    const auto t0 = Clock::now();
    for (int r = 0; r < robots; ++r) {
      threads.emplace_back(
          [&, r] { acked[r] = RunRobot(target, r, scans, per_robot, nullptr, &points[r]); });
    }
    for (auto& t : threads) t.join();
    const double s = Seconds(Clock::now() - t0);
    size_t total = 0;
    uint64_t total_points = 0;
    for (int r = 0; r < robots; ++r) {
      total += acked[r];
      total_points += points[r];
    }
    std::printf("| %d | %zu | %.2f | %.0f | %.3g |\n", robots, total, s, total / s,
                total_points / s);
    server->Shutdown();
  }
}

// Region and point query latencies through `client`.
void BenchQueries(Client& client) {
  std::printf(
      "\n| query (while 4 robots stream at 10 Hz) | n | p50 ms | p99 ms |\n"
      "|---|---|---|---|\n");
  struct Case {
    const char* name;
    double half;
    int n;
  };
  for (const Case& c : {Case{"region 50 x 50 m, 6 layers", 25.0, 200},
                        Case{"region 200 x 200 m, 6 layers", 100.0, 20}}) {
    std::vector<double> ms;
    for (int i = 0; i < c.n; ++i) {
      const auto t0 = Clock::now();
      auto r = client.QueryRegion({{-c.half, 105 - c.half, c.half, 105 + c.half}, {}, 1});
      ms.push_back(Seconds(Clock::now() - t0) * 1e3);
      if (!r.ok()) std::printf("error: %s\n", r.status().ToString().c_str());
    }
    std::printf("| %s | %d | %.2f | %.2f |\n", c.name, c.n, Percentile(ms, 0.5),
                Percentile(ms, 0.99));
  }
  std::vector<std::array<double, 2>> query_points;
  for (int i = 0; i < 1000; ++i) query_points.push_back({(i % 40) - 20.0, i * 0.2});
  std::vector<double> ms;
  for (int i = 0; i < 500; ++i) {
    const auto t0 = Clock::now();
    auto r = client.QueryPoints(query_points);
    ms.push_back(Seconds(Clock::now() - t0) * 1e3);
  }
  std::printf("| 1,000 points, 6 layers | 500 | %.2f | %.2f |\n", Percentile(ms, 0.5),
              Percentile(ms, 0.99));
}

}  // namespace

int main(int argc, char** argv) {
  bgkmap::KeepLargeAllocationsInHeap();  // as bgkmapd does
  const size_t per_robot = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 40;
  std::printf("simulating VLP-16 scans of the city...\n");
  const std::vector<SimScan> scans = SimulateCity(60);
  size_t pts = 0;
  for (const SimScan& s : scans) pts += s.points.size();
  std::printf("%zu scans, %.0f points per scan on average\n\n", scans.size(),
              static_cast<double>(pts) / scans.size());
  BenchIngest(scans, per_robot);

  // Queries while 4 robots stream.
  bgkmap::ServerConfig config;
  config.listen_address = "127.0.0.1:0";
  auto server = std::move(bgkmap::MapServer::Start(config)).value();
  const std::string target = "127.0.0.1:" + std::to_string(server->port());
  {
    // A mapped area first, so that queries read real tiles.
    uint64_t p = 0;
    RunRobot(target, 0, scans, scans.size(), nullptr, &p);
  }
  // Robots at 10 Hz, like real lidars (flat-out robots would measure CPU starvation instead).
  std::atomic<bool> stop{false};
  std::vector<std::thread> robots;
  std::vector<uint64_t> points(4, 0);
  for (int r = 0; r < 4; ++r) {
    robots.emplace_back([&, r] { RunRobot(target, r + 1, scans, 0, &stop, &points[r], 10.0); });
  }
  Client client(target);
  BenchQueries(client);
  stop = true;
  for (auto& t : robots) t.join();
  server->Shutdown();
  return 0;
}
