// Bytes on the wire per scan (issue 27), float32 against the compact encoding in the same run:
// every scan of each sequence goes through a byte-counting TCP proxy to a running bgkmapd, once
// as packed float32 points (what the clients sent before: ClientOptions::compact_step = 0, no
// filtering) and once as the clients' default (compact, without the points the map drops). The
// proxy counts every byte each way (TLS off; HTTP/2 and gRPC framing included), so the figure is
// what a radio carries. Also the ingest rate of each run (one stream, acks read concurrently).
// Sequences: simulated VLP-16 and HDL-32E on the benchmark street, and the real Ouster, KITTI
// and hall scans of ../shared/data.
//
//   bgkmapd --listen 127.0.0.1:50573 & wire_bytes --server 127.0.0.1:50573 --data ../shared/data
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/sim/ray_caster.h"
#include "street_world.h"

namespace bgkmap {
namespace {

struct Sequence {
  std::string name;
  std::vector<std::vector<Point3f>> scans;
  std::vector<Pose> poses;
};

Sequence Simulated(const std::string& name, const sim::BeamModel& beams, int count) {
  Sequence s{name, {}, {}};
  const bench::StreetWorld world;
  for (int i = 0; i < count; ++i) {
    Pose pose;
    pose.translation = {1.0 * i, 0.0, world.SurfaceHeight(1.0 * i, 0.0) + 0.8};
    sim::RayCastOptions opt;
    opt.seed = 1 + i;
    s.scans.push_back(sim::SimulateScan(world, beams, pose, opt));
    s.poses.push_back(pose);
  }
  return s;
}

Sequence Real(const std::string& name, const std::string& dir) {
  Sequence s{name, {}, {}};
  Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
  if (!seq.ok()) {
    std::fprintf(stderr, "wire_bytes: %s\n", seq.status().ToString().c_str());
    std::exit(1);
  }
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> scan = seq->Read(k);
    if (!scan.ok()) std::exit(1);
    s.scans.push_back(std::move(scan->points));
    s.poses.push_back(scan->pose);
  }
  return s;
}

// Forwards every connection made to its port to `server`, counting the bytes each way.
class CountingProxy {
 public:
  CountingProxy(const std::string& server_host, int server_port) {
    server_.sin_family = AF_INET;
    server_.sin_port = htons(static_cast<uint16_t>(server_port));
    inet_pton(AF_INET, server_host.c_str(), &server_.sin_addr);
    listen_fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in any{};
    any.sin_family = AF_INET;
    any.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof any;
    if (bind(listen_fd_, reinterpret_cast<sockaddr*>(&any), len) != 0 ||
        listen(listen_fd_, 16) != 0 ||
        getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&any), &len) != 0) {
      std::perror("wire_bytes: proxy");
      std::exit(1);
    }
    port_ = ntohs(any.sin_port);
    std::thread([this] { Accept(); }).detach();
  }

  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  uint64_t up() const { return up_; }
  uint64_t down() const { return down_; }

 private:
  void Accept() {
    for (;;) {
      const int client = accept(listen_fd_, nullptr, nullptr);
      if (client < 0) continue;
      const int server = socket(AF_INET, SOCK_STREAM, 0);
      if (connect(server, reinterpret_cast<const sockaddr*>(&server_), sizeof server_) != 0) {
        close(client);
        close(server);
        continue;
      }
      std::thread([this, client, server] { Pump(client, server, &up_); }).detach();
      std::thread([this, client, server] { Pump(server, client, &down_); }).detach();
    }
  }

  static void Pump(int from, int to, std::atomic<uint64_t>* count) {
    std::vector<char> buffer(1 << 16);
    for (;;) {
      const ssize_t n = read(from, buffer.data(), buffer.size());
      if (n <= 0) break;
      for (ssize_t done = 0; done < n;) {
        const ssize_t w = write(to, buffer.data() + done, static_cast<size_t>(n - done));
        if (w <= 0) return;
        done += w;
      }
      *count += static_cast<uint64_t>(n);
    }
    shutdown(to, SHUT_WR);
  }

  sockaddr_in server_{};
  int listen_fd_ = -1;
  int port_ = 0;
  std::atomic<uint64_t> up_{0}, down_{0};
};

struct Run {
  double up_per_scan = 0, down_per_scan = 0, scans_per_s = 0;
  uint64_t kept = 0;
};

Run Send(CountingProxy& proxy, const Sequence& s, bool compact, const std::string& robot) {
  ClientOptions options;
  if (!compact) {
    options.compact_step = 0;
    options.drop_filtered_points = false;
  }
  const uint64_t up0 = proxy.up(), down0 = proxy.down();
  const auto start = std::chrono::steady_clock::now();
  Run run;
  {
    Client client(proxy.target(), options);
    std::vector<ScanData> data(s.scans.size());
    for (size_t k = 0; k < s.scans.size(); ++k) {
      data[k].robot_id = robot;
      data[k].sequence = k + 1;
      data[k].pose = ScanPose::FromPose(s.poses[k]);
      data[k].points = s.scans[k];
    }
    RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
    if (!acks.ok() || acks->size() != data.size()) {
      std::fprintf(stderr, "wire_bytes: %s: ingest failed\n", robot.c_str());
      std::exit(1);
    }
    for (const ScanAck& a : *acks) run.kept += a.counts.kept;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // The channel is closed: every byte it moved has been counted (give the pumps a moment).
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const double n = static_cast<double>(s.scans.size());
  run.up_per_scan = static_cast<double>(proxy.up() - up0) / n;
  run.down_per_scan = static_cast<double>(proxy.down() - down0) / n;
  run.scans_per_s = n / seconds;
  return run;
}

int Main(int argc, char** argv) {
  CLI::App app{"Wire bytes per scan, float32 against compact"};
  std::string server = "127.0.0.1:50573", data;
  app.add_option("--server", server, "bgkmapd host:port")->capture_default_str();
  app.add_option("--data", data, "../shared/data")->required();
  CLI11_PARSE(app, argc, argv);
  const size_t colon = server.rfind(':');
  CountingProxy proxy(server.substr(0, colon), std::stoi(server.substr(colon + 1)));
  std::vector<Sequence> sequences;
  sequences.push_back(Simulated("simulated VLP-16", sim::Vlp16(), 24));
  sequences.push_back(Simulated("simulated HDL-32E", sim::Hdl32e(), 24));
  sequences.push_back(Real("Ouster OS1-128 street", data + "/ouster_os1_128_street"));
  sequences.push_back(Real("KITTI HDL-64E 0048", data + "/kitti_raw_0048"));
  sequences.push_back(Real("BALM hall", data + "/balm_hall"));
  std::printf(
      "| sequence | scans | points/scan | float32 bytes/scan | compact bytes/scan | ratio | "
      "acks bytes/scan (float32, compact) | scans/s float32 | scans/s compact |\n"
      "|---|---|---|---|---|---|---|---|---|\n");
  int robot = 0;
  for (const Sequence& s : sequences) {
    size_t points = 0;
    for (const auto& scan : s.scans) points += scan.size();
    const Run raw = Send(proxy, s, false, "f32-" + std::to_string(robot));
    const Run compact = Send(proxy, s, true, "compact-" + std::to_string(robot++));
    std::printf("| %s | %zu | %.0f | %.0f | %.0f | 1/%.1f | %.0f, %.0f | %.1f | %.1f |\n",
                s.name.c_str(), s.scans.size(),
                static_cast<double>(points) / static_cast<double>(s.scans.size()), raw.up_per_scan,
                compact.up_per_scan, raw.up_per_scan / compact.up_per_scan, raw.down_per_scan,
                compact.down_per_scan, raw.scans_per_s, compact.scans_per_s);
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) { return bgkmap::Main(argc, argv); }
