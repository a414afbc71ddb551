// KITTI-like scan sequences: `<dir>/velodyne/NNNNNN.bin` (little-endian float32 records
// {x, y, z, intensity}, sensor frame) and `<dir>/poses.txt` (line k = row-major 3x4 T_map_sensor
// of scan k). Scan files must be numbered 0..n-1 without gaps so that file k pairs with line k.
// An optional `<dir>/times.txt` (KITTI odometry) gives scan k's time in seconds on line k.
// The scans may instead be PCD files, `<dir>/velodyne/NNNNNN.pcd` (pcd_reader.h: x, y, z in the
// sensor frame), paired with poses.txt the same way; one kind per folder.
#pragma once

#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

// One scan of a sequence: points in the sensor frame and the pose that maps them to the map.
struct Scan {
  std::vector<Point3f> points;   // intensity is dropped
  Pose pose;                     // T_map_sensor
  double time_s = std::nan("");  // line k of times.txt, seconds; NaN without times.txt
};

class KittiSequence {
 public:
  // Lists the scans and parses every pose. Fails on a missing directory, a folder without
  // scans or with both .bin and .pcd scans, a gap in the scan numbering, a poses.txt line
  // without exactly 12 finite numbers, or fewer pose lines than scans. Extra pose lines are
  // ignored. Likewise times.txt, if present: one finite number of seconds per line, at least one
  // line per scan. Does not read the scans themselves.
  static Result<KittiSequence> Open(const std::string& directory);

  size_t size() const { return scan_paths_.size(); }
  const std::string& directory() const { return directory_; }
  const std::string& scan_path(size_t k) const { return scan_paths_[k]; }
  const Pose& pose(size_t k) const { return poses_[k]; }  // k < size()
  bool has_times() const { return !times_.empty(); }

  // Reads scan k (OutOfRange if k >= size()). A file whose size is not a multiple of 16 bytes
  // is DataLoss naming the file.
  Result<Scan> Read(size_t k) const;

 private:
  Result<Scan> ReadPcdScan(const std::string& path, size_t k) const;

  std::string directory_;
  std::vector<std::string> scan_paths_;
  std::vector<Pose> poses_;
  std::vector<double> times_;  // empty: no times.txt
};

// "000042.bin" for k = 42: the name of scan k inside velodyne/.
std::string KittiScanFileName(size_t k);

// Parses one poses.txt line (12 numbers, row-major 3x4). The error says what is wrong with the
// line; callers prefix the file and line number.
Result<Pose> ParseKittiPoseLine(std::string_view line);

// Writes one scan file. `intensity` is empty (written as 0) or one value per point.
Status WriteKittiScan(const std::string& path, std::span<const Point3f> points,
                      std::span<const float> intensity = {});

// Appends one line holding `pose` (round-trip exact) to a poses.txt, creating the file.
Status AppendPose(const std::string& poses_path, const Pose& pose);

}  // namespace bgkmap::io
