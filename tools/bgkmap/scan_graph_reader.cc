#include "scan_graph_reader.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <set>

namespace bgkmap::cli {
namespace {

// octomap's binary layout (little-endian, as written on x86): a vector is a u32 count (3 for a
// point, 4 for a quaternion w x y z) and that many f64; a pose is a point and a quaternion.
//   u32 nodes, then per node: u32 n, n points, pose, u32 id;
//   u32 edges, then per edge: u32 first id, u32 second id, pose, f64 weight.
constexpr uint64_t kPointBytes = 4 + 3 * 8;
constexpr uint64_t kPoseBytes = kPointBytes + 4 + 4 * 8;

// Reads the file front to back, checking every count and tag against the bytes left.
class GraphParser {
 public:
  GraphParser(std::ifstream& in, uint64_t size, const std::string& path)
      : in_(in), size_(size), path_(path) {}

  Status U32(const char* what, uint32_t& v) { return Raw(what, &v, 4); }
  Status F64(const char* what, double& v) { return Raw(what, &v, 8); }

  // A vector of N doubles with its count tag.
  template <size_t N>
  Status Vector(const char* what, std::array<double, N>& v) {
    uint32_t tag = 0;
    if (Status s = U32(what, tag); !s.ok()) return s;
    if (tag != N) {
      return Status::InvalidArgument(path_ + ": not an OctoMap scan graph: " + what + " at byte " +
                                     std::to_string(pos_ - 4) + " has " + std::to_string(tag) +
                                     " values, expected " + std::to_string(N));
    }
    return Raw(what, v.data(), N * 8);
  }

  Status ReadPose(const char* what, Pose& pose) {
    std::array<double, 3> t;
    std::array<double, 4> q;
    if (Status s = Vector(what, t); !s.ok()) return s;
    if (Status s = Vector(what, q); !s.ok()) return s;
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(norm > 1e-6) || !std::isfinite(norm) || !std::isfinite(t[0] + t[1] + t[2])) {
      return Status::InvalidArgument(
          path_ + ": " + what + " at byte " + std::to_string(pos_ - kPoseBytes) +
          " is no rigid pose (quaternion norm " + std::to_string(norm) + ")");
    }
    // octomap stores float-precision quaternions; ValidatePose wants a rigid rotation.
    pose =
        Pose::FromQuaternion(q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm, t[0], t[1], t[2]);
    return Status::Ok();
  }

  // `count` records of at least `bytes` each must fit in the rest of the file.
  Status Fits(const char* what, uint32_t count, uint64_t bytes) const {
    if (uint64_t{count} * bytes <= size_ - pos_) return Status::Ok();
    return Status::InvalidArgument(path_ + ": not an OctoMap scan graph or truncated: " + what +
                                   " at byte " + std::to_string(pos_ - 4) + " counts " +
                                   std::to_string(count) + " but only " +
                                   std::to_string(size_ - pos_) + " bytes are left");
  }

  uint64_t left() const { return size_ - pos_; }

 private:
  Status Raw(const char* what, void* out, uint64_t bytes) {
    if (bytes > size_ - pos_) {
      return Status::InvalidArgument(path_ + ": not an OctoMap scan graph or truncated: " + what +
                                     " at byte " + std::to_string(pos_) + " runs past the end (" +
                                     std::to_string(size_) + " bytes)");
    }
    in_.read(static_cast<char*>(out), static_cast<std::streamsize>(bytes));
    if (!in_) return Status::IoError(path_ + ": read error at byte " + std::to_string(pos_));
    pos_ += bytes;
    return Status::Ok();
  }

  std::ifstream& in_;
  uint64_t size_, pos_ = 0;
  const std::string& path_;
};

}  // namespace

Result<std::vector<GraphScan>> ReadScanGraph(const std::string& path) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) return Status::IoError(path + ": " + ec.message());
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError(path + ": cannot open");
  GraphParser p(in, size, path);

  uint32_t nodes = 0;
  if (Status s = p.U32("the node count", nodes); !s.ok()) return s;
  if (Status s = p.Fits("the node count", nodes, 4 + kPoseBytes + 4); !s.ok()) return s;
  std::vector<GraphScan> scans(nodes);
  std::set<uint32_t> ids;
  for (GraphScan& scan : scans) {
    uint32_t points = 0, id = 0;
    if (Status s = p.U32("a node's point count", points); !s.ok()) return s;
    if (Status s = p.Fits("a node's point count", points, kPointBytes); !s.ok()) return s;
    scan.points.reserve(points);
    for (uint32_t i = 0; i < points; ++i) {
      std::array<double, 3> v;
      if (Status s = p.Vector("a node's point", v); !s.ok()) return s;
      scan.points.push_back(
          {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])});
    }
    if (Status s = p.ReadPose("a node's pose", scan.pose); !s.ok()) return s;
    if (Status s = p.U32("a node's id", id); !s.ok()) return s;
    ids.insert(id);
  }

  // Edges carry no scans, but a graph whose edges do not join its nodes is corrupt.
  uint32_t edges = 0;
  if (Status s = p.U32("the edge count", edges); !s.ok()) return s;
  if (Status s = p.Fits("the edge count", edges, 8 + kPoseBytes + 8); !s.ok()) return s;
  for (uint32_t e = 0; e < edges; ++e) {
    uint32_t a = 0, b = 0;
    std::array<double, 3> t;
    std::array<double, 4> q;
    double weight = 0;
    if (Status s = p.U32("an edge", a); !s.ok()) return s;
    if (Status s = p.U32("an edge", b); !s.ok()) return s;
    if (!ids.contains(a) || !ids.contains(b)) {
      return Status::InvalidArgument(path + ": corrupt OctoMap scan graph: edge " +
                                     std::to_string(e) + " joins unknown node ids " +
                                     std::to_string(a) + " and " + std::to_string(b));
    }
    if (Status s = p.Vector("an edge's pose", t); !s.ok()) return s;
    if (Status s = p.Vector("an edge's pose", q); !s.ok()) return s;
    if (Status s = p.F64("an edge's weight", weight); !s.ok()) return s;
  }
  if (p.left() != 0) {
    return Status::InvalidArgument(path + ": not an OctoMap scan graph: " +
                                   std::to_string(p.left()) + " bytes after the last edge");
  }
  return scans;
}

}  // namespace bgkmap::cli
