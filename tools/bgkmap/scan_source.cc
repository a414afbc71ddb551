#include "scan_source.h"

#include <cmath>
#include <filesystem>

#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/las_reader.h"
#include "bgkmap/io/pcd_reader.h"
#include "bgkmap/io/point_cloud.h"
#include "scan_graph_reader.h"

namespace bgkmap::cli {
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

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Result<std::unique_ptr<ScanSource>> OpenScanSource(const std::string& path,
                                                   const SourceOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
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
      path + ": unknown input (expected a KITTI-like directory, .las, .pcd or .graph)");
}

}  // namespace bgkmap::cli
