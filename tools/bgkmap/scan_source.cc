#include "scan_source.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/las_reader.h"
#include "bgkmap/io/pcd_reader.h"
#include "bgkmap/io/point_cloud.h"
#include "bgkmap/io/ros_recording.h"
#include "scan_graph_reader.h"

namespace bgkmap::cli {

int64_t MapTimeNs(double time_s, double first_time_s) {
  if (!std::isfinite(time_s) || !std::isfinite(first_time_s)) return 0;
  return 1'000'000'000 + std::llround((time_s - first_time_s) * 1e9);
}

double ScanTimeS(const SourceScan& scan, size_t k, double rate_hz) {
  if (std::isfinite(scan.time_s)) return scan.time_s;
  if (scan.frame_is_map || !(rate_hz > 0)) return std::nan("");
  return static_cast<double>(k) / rate_hz;
}

namespace {

class KittiSource : public ScanSource {
 public:
  explicit KittiSource(io::KittiSequence seq) : seq_(std::move(seq)) {}
  size_t size() const override { return seq_.size(); }
  Result<SourceScan> Read(size_t k) const override {
    Result<io::Scan> s = seq_.Read(k);
    if (!s.ok()) return s.status();
    return SourceScan{std::move(s->points), s->pose, false, s->time_s};
  }
  std::string Describe() const override {
    return "KITTI-like sequence " + seq_.directory() + " (" + std::to_string(seq_.size()) +
           " scans)";
  }

 private:
  io::KittiSequence seq_;
};

// One cloud in map coordinates. Points are stored relative to a rounded origin carried in the
// pose translation, so float points keep millimetres even at UTM coordinates.
class CloudSource : public ScanSource {
 public:
  CloudSource(std::string path, const std::vector<io::Point3d>& points, std::string crs = {})
      : path_(std::move(path)), crs_(std::move(crs)) {
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    if (!points.empty()) {
      origin = {std::floor(points.front().x), std::floor(points.front().y), 0.0};
    }
    scan_.points = io::ToLocalFloat(points, origin);
    scan_.pose.translation = origin;
    scan_.frame_is_map = true;
  }
  size_t size() const override { return 1; }
  Result<SourceScan> Read(size_t) const override { return scan_; }
  std::string Describe() const override {
    return "point cloud " + path_ + " (" + std::to_string(scan_.points.size()) + " points)";
  }
  std::string spatial_reference() const override { return crs_; }
  bool map_frame_is_local() const override { return false; }

 private:
  std::string path_;
  std::string crs_;
  SourceScan scan_;
};

// An OctoMap scan graph: every node is a posed scan in its sensor frame.
class GraphSource : public ScanSource {
 public:
  GraphSource(std::string path, std::vector<GraphScan> scans)
      : path_(std::move(path)), scans_(std::move(scans)) {}
  size_t size() const override { return scans_.size(); }
  Result<SourceScan> Read(size_t k) const override {
    if (k >= scans_.size()) return Status::InvalidArgument("scan index out of range");
    return SourceScan{scans_[k].points, scans_[k].pose, false};
  }
  std::string Describe() const override {
    return "OctoMap scan graph " + path_ + " (" + std::to_string(scans_.size()) + " scans)";
  }

 private:
  std::string path_;
  std::vector<GraphScan> scans_;
};

// The clouds of a ROS 2 recording, posed through its TF tree; all decoded when opened.
class RecordingSource : public ScanSource {
 public:
  RecordingSource(std::string path, io::RecordingScans scans)
      : path_(std::move(path)), scans_(std::move(scans)) {}
  size_t size() const override { return scans_.scans.size(); }
  Result<SourceScan> Read(size_t k) const override {
    if (k >= size()) return Status::InvalidArgument("scan index out of range");
    const io::RecordingScan& s = scans_.scans[k];
    return SourceScan{s.points, s.pose, false, static_cast<double>(s.stamp_ns) * 1e-9};
  }
  std::string Describe() const override {
    return "ROS 2 recording " + path_ + ", topic " + scans_.topic + " (" + std::to_string(size()) +
           " clouds)";
  }
  size_t skipped() const override { return scans_.skipped; }
  std::string first_skip() const override { return scans_.first_skip; }

 private:
  std::string path_;
  io::RecordingScans scans_;
};

Result<std::unique_ptr<ScanSource>> OpenRecording(const std::string& path,
                                                  const SourceOptions& options) {
  Result<std::vector<io::RecordedMessage>> messages = io::ReadRecordedMessages(path);
  if (!messages.ok()) return messages.status();
  Result<io::RecordingScans> scans =
      io::ExtractScans(*messages, {options.topic, options.map_frame}, path);
  if (!scans.ok()) return scans.status();
  if (scans->scans.empty()) {
    return Status::InvalidArgument(path + ": no cloud on " + scans->topic +
                                   " could be placed in frame '" + options.map_frame + "'" +
                                   (scans->skipped ? " (" + scans->first_skip + ")" : ""));
  }
  return std::unique_ptr<ScanSource>(new RecordingSource(path, std::move(scans).value()));
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Result<std::unique_ptr<ScanSource>> OpenScanSource(const std::string& path,
                                                   const SourceOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (io::IsRosRecording(path)) return OpenRecording(path, options);
  if (fs::is_directory(path, ec)) {
    Result<io::KittiSequence> seq = io::KittiSequence::Open(path);
    if (!seq.ok()) return seq.status();
    return std::unique_ptr<ScanSource>(new KittiSource(std::move(seq).value()));
  }
  if (!fs::exists(path, ec)) return Status::IoError(path + ": no such file or directory");
  const std::string ext = Lower(fs::path(path).extension().string());
  if (ext == ".las") {
    io::LasReadOptions opt;
    opt.classes = options.las_classes;
    Result<io::LasCloud> cloud = io::ReadLas(path, opt);
    if (!cloud.ok()) return cloud.status();
    return std::unique_ptr<ScanSource>(new CloudSource(path, cloud->points, cloud->header.crs));
  }
  if (ext == ".pcd") {
    Result<io::PcdCloud> cloud = io::ReadPcd(path);
    if (!cloud.ok()) return cloud.status();
    return std::unique_ptr<ScanSource>(new CloudSource(path, cloud->points));
  }
  if (ext == ".graph") {
    Result<std::vector<GraphScan>> scans = ReadScanGraph(path);
    if (!scans.ok()) return scans.status();
    return std::unique_ptr<ScanSource>(new GraphSource(path, std::move(scans).value()));
  }
  return Status::InvalidArgument(
      path +
      ": unknown input (expected a KITTI-like directory, .mcap, .db3, a rosbag2 folder, .las, "
      ".pcd or .graph)");
}

void AddRecordingOptions(CLI::App* cmd, SourceOptions& options) {
  cmd->add_option("--topic", options.topic,
                  "Recording: the sensor_msgs/msg/PointCloud2 topic (default: the only one)");
  cmd->add_option("--map-frame", options.map_frame, "Recording: the TF frame of the map")
      ->capture_default_str();
}

void ReportSkipped(const char* command, const ScanSource& source, const SourceOptions& options) {
  if (source.skipped() == 0) return;
  std::fprintf(stderr, "bgkmap %s: skipped %zu clouds with no transform to '%s' (first: %s)\n",
               command, source.skipped(), options.map_frame.c_str(), source.first_skip().c_str());
}

}  // namespace bgkmap::cli
