// `bgkmap insert`: streams a scan sequence to bgkmapd as one robot, resuming where the server's
// record of that robot ends (sequence number k+1 is scan k).
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

#include "bgkmap/io/progress_bar.h"
#include "client_options.h"
#include "commands.h"
#include "scan_read_ahead.h"
#include "scan_source.h"
#include "served_map_alignment.h"

namespace bgkmap::cli {
namespace {

// Scans read ahead of the one being sent.
constexpr size_t kReadAhead = 2;

struct InsertOptions {
  ServerTarget server;
  std::string input, robot = "robot";
  SourceOptions source;
  double rate_hz = 0;  // 0: as fast as flow control allows
  bool restart = false;
  // Align each scan's z to the served map before sending it (served_map_alignment.h).
  bool align_z = false;
  ServedAlignmentOptions align;
};

// Counts the acks read, so a sender can wait until the server has answered every scan sent
// (--align-z aligns each scan against a map that holds the ones before it).
class AckCounter {
 public:
  void Add() {
    std::lock_guard lock(mu_);
    ++count_;
    cv_.notify_all();
  }
  // Returns once n acks were read, or the stream ended.
  void WaitFor(uint64_t n) {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [&] { return count_ >= n || ended_; });
  }
  void End() {
    std::lock_guard lock(mu_);
    ended_ = true;
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  uint64_t count_ = 0;
  bool ended_ = false;
};

void PrintAlignment(const ServedAlignmentStats& a) {
  const double scans = static_cast<double>(a.aligned + a.not_aligned);
  if (scans == 0) return;
  std::printf(
      "bgkmap insert: --align-z: %llu scans aligned (mean |dz| %.3f m, max %.3f m), %llu not "
      "(too few cells in common or beyond the bound); per scan %.0f kB of region, %.1f ms\n",
      static_cast<unsigned long long>(a.aligned),
      a.aligned > 0 ? a.sum_abs_dz / static_cast<double>(a.aligned) : 0.0, a.max_abs_dz,
      static_cast<unsigned long long>(a.not_aligned),
      static_cast<double>(a.region_bytes) / scans / 1000.0, 1000.0 * a.seconds / scans);
  if (a.levelled > 0) {
    std::printf("bgkmap insert: --align-tilt: %llu scans levelled (largest tilt %.3f deg)\n",
                static_cast<unsigned long long>(a.levelled), a.max_tilt_deg);
  }
}

// What is wrong with the options, or "" (checked before anything is read or sent).
std::string OptionsError(const InsertOptions& o) {
  if (o.rate_hz < 0 || !std::isfinite(o.rate_hz)) return "--rate must be >= 0";
  if (!(o.align.align.radius_m > 0) || o.align.stride < 1)
    return "--align-z-radius must be > 0 and --align-z-stride >= 1";
  if (!(o.align.align.max_tilt_deg >= 0 && o.align.align.max_tilt_deg <= 10))
    return "--align-tilt must be between 0 and 10 degrees";
  if (o.align.align.max_tilt_deg > 0 && !o.align_z)
    return "--align-tilt levels what --align-z compares: give both";
  return "";
}

int RunInsert(const InsertOptions& o) {
  if (const std::string error = OptionsError(o); !error.empty()) return Usage("insert", error);
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.input, o.source);
  if (!source.ok()) return Fail("insert", source.status().message());
  ReportSkipped("insert", **source, o.source);
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("insert", connected.status().message());
  Client& client = **connected;
  if (!client.WaitForConnected(std::chrono::seconds(10))) {
    return Fail("insert", "cannot reach bgkmapd at " + o.server.address);
  }
  // Resume: the server remembers the last sequence number it admitted for this robot.
  uint64_t first = 0;
  if (!o.restart) {
    RpcResult<std::optional<uint64_t>> last = client.LastSequence(o.robot);
    if (!last.ok()) return Fail("insert", last.status().ToString());
    if (*last) first = std::min<uint64_t>(**last, (*source)->size());
  }
  if (first > 0) {
    std::fprintf(stderr, "bgkmap insert: robot %s resumes after sequence %llu\n", o.robot.c_str(),
                 static_cast<unsigned long long>(first));
  }
  MapParams map_params;  // the served map's, to prepare scans as it does (--align-z)
  if (o.align_z) {
    RpcResult<MapInfo> info = client.Info();
    if (!info.ok()) return Fail("insert", "--align-z needs Info: " + info.status().ToString());
    map_params = info->params;
  }
  AckCounter acked;
  ServedAlignmentStats alignment;

  std::unique_ptr<IngestStream> stream = client.OpenIngest();
  uint64_t applied = 0, duplicate = 0, rejected = 0, kept = 0, dropped = 0;
  std::string first_rejection;
  io::ProgressBar progress("inserting", (*source)->size() - first, "scans");
  // Acks arrive in send order on their own thread, so sending never waits for a round trip.
  std::thread acks([&] {
    ScanAck ack;
    while (stream->ReadAck(&ack)) {
      switch (ack.status) {
        case AckStatus::kApplied:
          ++applied;
          break;
        case AckStatus::kDuplicate:
          ++duplicate;
          break;
        case AckStatus::kRejected:
          if (rejected++ == 0) {
            first_rejection =
                "sequence " + std::to_string(ack.sequence) + ": " + ack.error.ToString();
          }
          break;
      }
      kept += ack.counts.kept;
      dropped += ack.counts.input - ack.counts.kept;
      progress.Add();
      acked.Add();
    }
    acked.End();
  });
  const auto start = std::chrono::steady_clock::now();
  const auto period = o.rate_hz > 0 ? std::chrono::duration<double>(1.0 / o.rate_hz)
                                    : std::chrono::duration<double>(0);
  std::string read_error;
  int64_t start_ns = 0;
  double first_time = std::nan("");
  // The next scans are read while this one is encoded and sent (the client's stream encodes on
  // threads of its own, ClientOptions::ingest_encode_threads).
  ScanReadAhead reader(**source, first, kReadAhead);
  for (size_t k = first; k < (*source)->size(); ++k) {
    Result<SourceScan> scan = reader.Next();
    if (!scan.ok()) {
      read_error = scan.status().message();
      break;
    }
    if (scan->frame_is_map) {
      read_error = o.input +
                   ": a single map-frame cloud cannot be streamed as a sensor scan; "
                   "use `bgkmap build` for LAS/PCD clouds";
      break;
    }
    if (o.rate_hz > 0) {
      std::this_thread::sleep_until(start + std::chrono::duration_cast<std::chrono::nanoseconds>(
                                                period * static_cast<double>(k - first)));
    }
    ScanData data;
    data.robot_id = o.robot;
    data.sequence = k + 1;
    // The scan's map time (forgetting ages evidence by it): with times.txt, the sequence's own
    // timing from the moment the insert started, whatever the rate; else the clock.
    const int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
    if (k == first) {
      start_ns = now_ns;
      first_time = scan->time_s;
    }
    data.stamp_ns = std::isfinite(scan->time_s) && std::isfinite(first_time)
                        ? start_ns + std::llround((scan->time_s - first_time) * 1e9)
                        : now_ns;
    Pose pose = scan->pose;
    if (o.align_z) {
      acked.WaitFor(k - first);  // the map holds every scan sent before this one
      Result<VerticalAlignment> a =
          AlignToServedMap(client, map_params, scan->points, pose, o.align, &alignment);
      if (!a.ok()) {
        read_error = a.status().message();
        break;
      }
      pose = AlignedPose(pose, *a);
    }
    data.pose = ScanPose::FromPose(pose);
    data.points = scan->points;
    if (!stream->Send(data)) break;
  }
  // One reader at a time: the ack thread drains the stream, then Finish() reports how it ended.
  stream->CloseSend();
  acks.join();
  const RpcStatus end = stream->Finish();
  progress.Finish();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!read_error.empty()) return Fail("insert", read_error);
  if (!end.ok()) return Fail("insert", "stream ended: " + end.ToString());
  std::printf(
      "bgkmap insert: robot %s, %llu applied, %llu duplicate, %llu rejected, %llu points kept, "
      "%llu dropped, %.2f s (%.1f scans/s)\n",
      o.robot.c_str(), static_cast<unsigned long long>(applied),
      static_cast<unsigned long long>(duplicate), static_cast<unsigned long long>(rejected),
      static_cast<unsigned long long>(kept), static_cast<unsigned long long>(dropped), seconds,
      seconds > 0 ? static_cast<double>(applied + duplicate) / seconds : 0.0);
  if (o.align_z) PrintAlignment(alignment);
  if (rejected > 0) return Fail("insert", first_rejection);
  return 0;
}

}  // namespace

void RegisterInsertCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<InsertOptions>();
  CLI::App* cmd = app.add_subcommand(
      "insert", "Stream a KITTI-like scan sequence or a ROS 2 recording to bgkmapd");
  AddServerOption(cmd, o->server);
  cmd->add_option("input", o->input,
                  "KITTI-like directory, or a ROS 2 recording (.mcap, .db3, rosbag2 folder)")
      ->required();
  AddRecordingOptions(cmd, o->source);
  cmd->add_option("--robot", o->robot, "Robot id (sequence numbers are per robot)")
      ->capture_default_str();
  cmd->add_option("--rate", o->rate_hz,
                  "Pace the scans at this rate in Hz (0: as fast as possible)");
  cmd->add_flag("--restart", o->restart,
                "Send from the first scan even if the server has seen this robot (they are "
                "acknowledged as duplicates)");
  cmd->add_flag("--float32", o->server.float32_points,
                "Send the points as packed float32 (12 bytes each), not compact (quantized to "
                "2 mm, zstd; docs/server.md \"Compact scans\")");
  cmd->add_flag("--align-z", o->align_z,
                "Align each scan's z to the served map before sending it, as a localization "
                "with vertical drift would (docs/mapping-your-robot.md, \"Vertical alignment\"): "
                "waits for each scan's ack, then one region query per scan");
  cmd->add_option("--align-tilt", o->align.align.max_tilt_deg,
                  "With --align-z: also level each scan's roll and pitch against the map, up to "
                  "this many degrees (0: off; docs/mapping-your-robot.md, \"Levelling the tilt\")")
      ->capture_default_str();
  cmd->add_option("--align-z-radius", o->align.align.radius_m,
                  "With --align-z: compare the cells within this distance of the sensor (m)")
      ->capture_default_str();
  cmd->add_option("--align-z-stride", o->align.stride,
                  "With --align-z: map cells per pixel edge of the region query")
      ->capture_default_str();
  cmd->callback([o, &exit_code] { exit_code = RunInsert(*o); });
}

}  // namespace bgkmap::cli
