// MCAP read + integrate throughput against the same scans as a KITTI-like folder (issue 26):
// each run opens the input, reads every scan and integrates it into a fresh map with default
// parameters, as `bgkmap build` does (io::ReadRecordedMessages + ExtractScans: the whole
// recording is read, decompressed, CRC-checked and decoded first; the folder reads one .bin per
// scan). Runs alternate folder and recordings, `--repeat` times; reports the median of each and
// the ratio to the folder, and the read-only time (no integration) the same way.
//   recording_read <folder> <recording.mcap>... [--repeat 5]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/ros_recording.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "recording_read: %s\n", what.c_str());
  std::exit(1);
}

struct Run {
  double seconds = 0;
  size_t scans = 0, points = 0;
};

Run Integrate(const std::vector<std::pair<std::vector<Point3f>, Pose>>& scans, bool integrate,
              Clock::time_point start) {
  Run run;
  auto map = TerrainMap::Create(MapParams{});
  if (!map.ok()) Die(map.status().message());
  for (const auto& [points, pose] : scans) {
    if (integrate && !(*map)->IntegrateScan(points, pose).ok()) Die("integration failed");
    ++run.scans;
    run.points += points.size();
  }
  run.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return run;
}

// Reading and integrating one scan at a time, as `bgkmap build` does with a folder.
Run FromFolder(const std::string& dir, bool integrate) {
  const auto start = Clock::now();
  Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
  if (!seq.ok()) Die(seq.status().message());
  auto map = TerrainMap::Create(MapParams{});
  if (!map.ok()) Die(map.status().message());
  Run run;
  for (size_t k = 0; k < seq->size(); ++k) {
    Result<io::Scan> s = seq->Read(k);
    if (!s.ok()) Die(s.status().message());
    if (integrate && !(*map)->IntegrateScan(s->points, s->pose).ok()) Die("integration failed");
    ++run.scans;
    run.points += s->points.size();
  }
  run.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return run;
}

Run FromRecording(const std::string& path, bool integrate) {
  const auto start = Clock::now();
  Result<std::vector<io::RecordedMessage>> messages = io::ReadRecordedMessages(path);
  if (!messages.ok()) Die(messages.status().message());
  Result<io::RecordingScans> rec = io::ExtractScans(*messages, {}, path);
  if (!rec.ok()) Die(rec.status().message());
  std::vector<std::pair<std::vector<Point3f>, Pose>> scans;
  for (io::RecordingScan& s : rec->scans) scans.emplace_back(std::move(s.points), s.pose);
  return Integrate(scans, integrate, start);
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) {
  using namespace bgkmap;
  std::vector<std::string> inputs;
  int repeat = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      repeat = std::atoi(argv[++i]);
    } else {
      inputs.push_back(a);
    }
  }
  if (inputs.size() < 2 || repeat < 1)
    Die("usage: recording_read <folder> <recording>... [--repeat N]");
  std::printf(
      "| input | scans | points | read s (median) | read ratio | read + integrate s (median) | "
      "ratio to folder |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  std::vector<std::vector<double>> read(inputs.size()), full(inputs.size());
  std::vector<Run> last(inputs.size());
  for (int r = 0; r < repeat; ++r) {
    for (size_t k = 0; k < inputs.size(); ++k) {
      for (bool integrate : {false, true}) {
        last[k] = k == 0 ? FromFolder(inputs[k], integrate) : FromRecording(inputs[k], integrate);
        (integrate ? full : read)[k].push_back(last[k].seconds);
      }
    }
  }
  for (size_t k = 0; k < inputs.size(); ++k) {
    std::printf("| %s | %zu | %zu | %.3f | %.2f | %.3f | %.3f |\n", inputs[k].c_str(),
                last[k].scans, last[k].points, Median(read[k]), Median(read[k]) / Median(read[0]),
                Median(full[k]), Median(full[k]) / Median(full[0]));
  }
  return 0;
}
