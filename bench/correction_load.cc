// Pose corrections against a running bgkmapd with a data directory (issue: pose corrections):
//  1. a 1,000-scan VLP-16 drive streamed with drifting odometry: the time of that ingest is what a
//     full rebuild from the raw scans costs;
//  2. correcting 10 % of it to the true poses: the last 100 scans (a loop closure at the end) and
//     100 in the middle (a closure reaching back);
//  3. while a correction of 100 scans runs: another robot's ingest rate 600 m away and point
//     query latency there, against the same without a correction.
//
//   bgkmapd --data-dir /tmp/x --listen 127.0.0.1:50572 & correction_load --server 127.0.0.1:50572
#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/sim/odometry_drift.h"
#include "bgkmap/sim/ray_caster.h"
#include "percentile.h"
#include "street_world.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// A drive along the street, 0.5 m per scan (10 Hz at 5 m/s), 24 distinct simulated scans reused
// (the street repeats every 60 m): scan k at x = 0.5 k (+ `offset`).
struct Drive {
  std::vector<std::vector<Point3f>> scans;  // 120 distinct ones
  std::vector<Pose> truth;
  Drive(int n, double offset) {
    const bench::StreetWorld world;
    for (int i = 0; i < 120; ++i) {
      Pose pose;
      pose.translation = {0.5 * i, 0.0, world.SurfaceHeight(0.5 * i, 0.0) + 0.8};
      sim::RayCastOptions opt;
      opt.seed = 1 + i;
      scans.push_back(sim::SimulateScan(world, sim::Vlp16(), pose, opt));
    }
    for (int k = 0; k < n; ++k) {
      Pose pose;
      pose.translation = {offset + 0.5 * k, 0.0, world.SurfaceHeight(0.5 * (k % 120), 0.0) + 0.8};
      truth.push_back(pose);
    }
  }
  ScanData Scan(const std::string& robot, const std::vector<Pose>& poses, size_t k) const {
    ScanData s;
    s.robot_id = robot;
    s.sequence = k + 1;
    s.stamp_ns = static_cast<int64_t>(k) * 100'000'000;
    s.pose = ScanPose::FromPose(poses[k]);
    s.points = scans[k % scans.size()];
    return s;
  }
};

double Stream(Client& client, const Drive& d, const std::string& robot,
              const std::vector<Pose>& poses, size_t from, size_t to,
              const std::atomic<bool>* stop = nullptr, size_t* sent = nullptr) {
  const auto start = Clock::now();
  std::unique_ptr<IngestStream> stream = client.OpenIngest();
  std::thread reader([&] {
    ScanAck ack;
    while (stream->ReadAck(&ack)) {
    }
  });
  size_t k = from;
  for (; k < to && !(stop && stop->load()); ++k) {
    if (!stream->Send(d.Scan(robot, poses, k))) break;
  }
  stream->CloseSend();
  reader.join();
  stream->Finish();
  if (sent) *sent = k - from;
  return Seconds(start);
}

struct Load {
  double scans_per_s = 0;
  double p50_ms = 0, p99_ms = 0;
};

// Another robot streams and point queries run until `busy` returns; measured over that time.
Load MeasureLoad(Client& client, const Drive& other, const std::function<void()>& busy) {
  std::atomic<bool> stop{false};
  size_t sent = 0;
  double stream_s = 0;
  std::thread robot([&] {
    stream_s = Stream(client, other, "other", other.truth, 0, other.truth.size(), &stop, &sent);
  });
  std::vector<double> ms;
  std::thread queries([&] {
    std::vector<std::array<double, 2>> pts;
    for (int i = 0; i < 1000; ++i) pts.push_back({other.truth[0].translation.x() + 0.05 * i, 1.0});
    while (!stop) {
      const auto t0 = Clock::now();
      (void)client.QueryPoints(pts);
      ms.push_back(1e3 * Seconds(t0));
    }
  });
  busy();
  stop = true;
  robot.join();
  queries.join();
  return {static_cast<double>(sent) / std::max(stream_s, 1e-9), bench::Percentile(ms, 0.5),
          bench::Percentile(ms, 0.99)};
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) {
  using namespace bgkmap;
  CLI::App app{"Pose corrections against a running bgkmapd (with --data-dir)"};
  std::string server = "127.0.0.1:50572";
  int scans = 1000;
  app.add_option("--server", server, "bgkmapd address")->capture_default_str();
  app.add_option("--scans", scans, "Scans of the drive")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  Client client(server);
  if (!client.WaitForConnected(std::chrono::seconds(10))) {
    std::fprintf(stderr, "correction_load: cannot reach %s\n", server.c_str());
    return 1;
  }
  const Drive drive(scans, 0.0), other(100'000, 600.0);
  sim::DriftOptions drift;  // 1 % of distance, 0.2 degrees per 10 m... (odometry_drift.h)
  const std::vector<Pose> odometry = sim::DriftedOdometry(drive.truth, drift);
  const size_t n = drive.truth.size(), tenth = n / 10;

  const double ingest_s = Stream(client, drive, "drive", odometry, 0, n);
  std::printf("| step | scans | seconds | records replayed |\n|---|---|---|---|\n");
  std::printf("| ingest of the drive (= a full rebuild from raw scans) | %zu | %.2f | |\n", n,
              ingest_s);
  auto correct = [&](size_t first, const char* what, bool print = true) {
    std::vector<std::pair<uint64_t, ScanPose>> poses;
    for (size_t k = first; k < first + tenth; ++k) {
      poses.emplace_back(k + 1, ScanPose::FromPose(drive.truth[k]));
    }
    const auto t0 = Clock::now();
    RpcResult<CorrectionResult> r = client.CorrectPoses("drive", poses);
    const double s = Seconds(t0);
    if (!r.ok()) {
      std::fprintf(stderr, "correction_load: %s\n", r.status().ToString().c_str());
      std::exit(1);
    }
    if (!print) return;
    std::printf("| correct %s | %zu | %.2f | %llu of %llu |\n", what, tenth, s,
                static_cast<unsigned long long>(r->records_replayed),
                static_cast<unsigned long long>(r->records_in_history));
  };
  correct(n - tenth, "the last 10 %");
  correct(n / 2 - tenth / 2, "10 % in the middle");

  std::printf("\n| another robot 600 m away | its scans/s | point query p50 ms | p99 ms |\n");
  std::printf("|---|---|---|---|\n");
  const Load idle =
      MeasureLoad(client, other, [] { std::this_thread::sleep_for(std::chrono::seconds(3)); });
  std::printf("| no correction running (3 s) | %.0f | %.2f | %.2f |\n", idle.scans_per_s,
              idle.p50_ms, idle.p99_ms);
  const Load busy = MeasureLoad(client, other, [&] { correct(n / 2 - tenth / 2, "", false); });
  std::printf("| while 100 scans are corrected | %.0f | %.2f | %.2f |\n", busy.scans_per_s,
              busy.p50_ms, busy.p99_ms);
  return 0;
}
