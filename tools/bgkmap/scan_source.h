// Where the CLI's scans come from: a KITTI-like directory, an OctoMap scan graph or a ROS 2
// recording (sequences of posed scans), or a single georeferenced cloud (LAS, PCD), which is one
// scan in the map frame.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace CLI {
class App;
}

namespace bgkmap::cli {

struct SourceScan {
  std::vector<Point3f> points;  // sensor frame, or map frame minus pose.translation
  Pose pose;
  bool frame_is_map = false;     // a single cloud: no sensor, no range/height filtering
  double time_s = std::nan("");  // the scan's time in seconds (KITTI times.txt); NaN: none
};

// The map time (forgetting's clock, ns) of a scan taken at `time_s` in a sequence whose first
// scan was taken at `first_time_s`: 1 s plus the time since the first scan (0 would be
// unstamped); 0, unstamped, when either time is unknown (NaN).
int64_t MapTimeNs(double time_s, double first_time_s);

// The time of scan `k` of a sequence, seconds: its own (times.txt); a sensor's scan without one
// (a KITTI-like directory without times.txt) is taken at its nominal rate, k / rate_hz, so the
// rules on map time (forgetting, transient objects) act on such a drive too; NaN (unstamped) for a
// cloud in the map frame without a time, or with rate_hz 0.
double ScanTimeS(const SourceScan& scan, size_t k, double rate_hz);

struct SourceOptions {
  std::vector<uint8_t> las_classes;  // keep only these LAS classes (empty = all)
  std::string topic;                 // a recording's PointCloud2 topic (empty: its only one)
  std::string map_frame = "map";     // a recording's frame the scans are posed in
};

class ScanSource {
 public:
  virtual ~ScanSource() = default;
  virtual size_t size() const = 0;
  virtual Result<SourceScan> Read(size_t k) const = 0;
  virtual std::string Describe() const = 0;
  // The coordinate reference system the input declares (a LAS file's), or empty.
  virtual std::string spatial_reference() const { return {}; }
  // Scans of the input that cannot be used and were left out (a recording's clouds with no
  // transform to the map frame), and why the first one was.
  virtual size_t skipped() const { return 0; }
  virtual std::string first_skip() const { return {}; }
  // Whether the map frame is the input's own local frame (a scan sequence: the first scan's
  // pose) rather than the coordinates the input was given in (a cloud).
  virtual bool map_frame_is_local() const { return true; }
};

// Picks the reader from the path: *.mcap, *.db3 and a folder with a metadata.yaml are ROS 2
// recordings (io/ros_recording.h), another directory is KITTI-like, *.graph an OctoMap scan
// graph (one scan per node), *.las and *.pcd are single clouds.
Result<std::unique_ptr<ScanSource>> OpenScanSource(const std::string& path,
                                                   const SourceOptions& options = {});

// Registers a recording's --topic and --map-frame on `cmd`, stored into `options`.
void AddRecordingOptions(CLI::App* cmd, SourceOptions& options);

// One stderr line "bgkmap <command>: skipped N clouds ..." if the source left scans out.
void ReportSkipped(const char* command, const ScanSource& source, const SourceOptions& options);

}  // namespace bgkmap::cli
