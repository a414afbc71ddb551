#include "rpc/request_checks.h"

#include <cmath>
#include <cstring>
#include <sstream>
#include <vector>

#include "bgkmap/proto/scan_codec.h"
#include "rpc/proto_convert.h"

namespace bgkmap {
namespace {

constexpr size_t kMaxRobotIdBytes = 128;
constexpr size_t kBytesPerPoint = 3 * sizeof(float);

grpc::Status Invalid(const std::string& message) {
  return {grpc::StatusCode::INVALID_ARGUMENT, message};
}

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

grpc::Status CheckPose(const v1::Pose3& pose, const MapParams& params, const ServerLimits& limits,
                       Pose* out) {
  const v1::Vector3& t = pose.translation();
  const double tv[3] = {t.x(), t.y(), t.z()};
  const char* axis[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    if (grpc::Status s = CheckCoordinate(tv[i], std::string("pose.translation.") + axis[i], limits);
        !s.ok()) {
      return s;
    }
  }
  const v1::Quaternion& q = pose.rotation();
  const double qv[4] = {q.w(), q.x(), q.y(), q.z()};
  const char* qaxis[4] = {"w", "x", "y", "z"};
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(qv[i])) {
      return Invalid(std::string("pose.rotation.") + qaxis[i] + ": " + Num(qv[i]) +
                     " is not finite");
    }
  }
  const double norm = std::sqrt(qv[0] * qv[0] + qv[1] * qv[1] + qv[2] * qv[2] + qv[3] * qv[3]);
  if (!(std::abs(norm - 1.0) <= limits.quaternion_tolerance)) {
    return Invalid(
        "pose.rotation: quaternion norm " + Num(norm) +
        " is not 1 within server.quaternion_tolerance = " + Num(limits.quaternion_tolerance));
  }
  *out = Pose::FromQuaternion(qv[0] / norm, qv[1] / norm, qv[2] / norm, qv[3] / norm, tv[0], tv[1],
                              tv[2]);
  if (Status s = ValidatePose(*out, params); !s.ok()) {
    return Invalid("pose: " + s.message());
  }
  return grpc::Status::OK;
}

grpc::Status CheckRobotId(const std::string& robot_id) {
  if (robot_id.empty()) return Invalid("robot_id: must not be empty");
  if (robot_id.size() > kMaxRobotIdBytes) {
    return Invalid("robot_id: " + std::to_string(robot_id.size()) + " bytes exceed the limit of " +
                   std::to_string(kMaxRobotIdBytes));
  }
  // Ids are written into logs, metrics labels and the store: no control characters (a newline
  // or NUL could forge a log line).
  for (size_t i = 0; i < robot_id.size(); ++i) {
    const auto c = static_cast<unsigned char>(robot_id[i]);
    if (c < 0x20 || c == 0x7f) {
      static constexpr char kHex[] = "0123456789abcdef";
      return Invalid(std::string("robot_id: byte ") + std::to_string(i) +
                     " is the control character 0x" + kHex[c >> 4] + kHex[c & 15] +
                     "; robot ids must be printable text");
    }
  }
  return grpc::Status::OK;
}

grpc::Status CheckCoordinate(double value, const std::string& field, const ServerLimits& limits) {
  if (!std::isfinite(value)) return Invalid(field + ": " + Num(value) + " is not finite");
  if (std::abs(value) > limits.max_coordinate) {
    return Invalid(field + ": |" + Num(value) +
                   "| exceeds server.max_coordinate = " + Num(limits.max_coordinate) + " m");
  }
  return grpc::Status::OK;
}

namespace {

// The scan's points in the sensor frame: the packed float32 ones as sent, or the compact ones
// dequantized (docs/server.md "Compact scans"), within server.max_points_per_scan.
grpc::Status ScanPoints(const v1::Scan& scan, const ServerLimits& limits,
                        std::vector<Point3f>* points) {
  const std::string& bytes = scan.points();
  if (scan.has_compact_points()) {
    if (!bytes.empty()) {
      return Invalid("points and compact_points: both set; send the points one way");
    }
    const uint32_t count = scan.compact_points().count();
    if (count > limits.max_points_per_scan) {
      return Invalid("compact_points.count: " + std::to_string(count) +
                     " points exceed server.max_points_per_scan = " +
                     std::to_string(limits.max_points_per_scan));
    }
    Result<std::vector<Point3f>> decoded =
        DecodeCompactPoints(FromProto(scan.compact_points()), limits.max_points_per_scan);
    if (!decoded.ok()) return Invalid(decoded.status().message());
    *points = std::move(decoded).value();
    return grpc::Status::OK;
  }
  if (bytes.size() % kBytesPerPoint != 0) {
    return Invalid("points: " + std::to_string(bytes.size()) +
                   " bytes is not a multiple of 12 (packed little-endian float32 x, y, z)");
  }
  const size_t count = bytes.size() / kBytesPerPoint;
  if (count > limits.max_points_per_scan) {
    return Invalid("points: " + std::to_string(count) +
                   " points exceed server.max_points_per_scan = " +
                   std::to_string(limits.max_points_per_scan));
  }
  static_assert(sizeof(Point3f) == kBytesPerPoint);
  points->resize(count);
  if (count > 0) std::memcpy(points->data(), bytes.data(), bytes.size());
  return grpc::Status::OK;
}

}  // namespace

grpc::Status PrepareScanMessage(const v1::Scan& scan, const MapParams& params,
                                const ServerLimits& limits, PreparedScan* out,
                                std::shared_ptr<RawScan>* raw, const Pose* pose_override) {
  if (grpc::Status s = CheckRobotId(scan.robot_id()); !s.ok()) return s;
  std::vector<Point3f> points;
  if (grpc::Status s = ScanPoints(scan, limits, &points); !s.ok()) return s;
  if (!scan.has_pose()) return Invalid("pose: missing");
  Pose pose;
  if (grpc::Status s = CheckPose(scan.pose(), params, limits, &pose); !s.ok()) return s;
  if (pose_override != nullptr) pose = *pose_override;

  Result<PreparedScan> prepared = PrepareScan(params, points, pose);
  if (!prepared.ok()) return ToGrpcStatus(prepared.status());
  *out = std::move(prepared).value();
  // The map time forgetting ages evidence by; a sender's absurd seconds must not overflow (0:
  // unstamped).
  int64_t stamp_ns = 0;
  if (__builtin_mul_overflow(scan.stamp().seconds(), int64_t{1'000'000'000}, &stamp_ns) ||
      __builtin_add_overflow(stamp_ns, int64_t{scan.stamp().nanos()}, &stamp_ns)) {
    stamp_ns = 0;
  }
  out->stamp_ns = stamp_ns;
  if (raw != nullptr) {
    auto sent = std::make_shared<RawScan>();
    sent->pose = pose;
    sent->points = std::move(points);
    if (scan.has_compact_points()) sent->quantum = scan.compact_points().step();
    *raw = std::move(sent);
  }
  return grpc::Status::OK;
}

grpc::Status RegionCells(const v1::BoundingBox& box, const std::string& field,
                         const GridGeometry& g, int stride, const ServerLimits& limits,
                         bool limit_cells, CellBox* out) {
  const double v[4] = {box.min_x(), box.min_y(), box.max_x(), box.max_y()};
  const char* names[4] = {"min_x", "min_y", "max_x", "max_y"};
  for (int i = 0; i < 4; ++i) {
    if (grpc::Status s = CheckCoordinate(v[i], field + "." + names[i], limits); !s.ok()) return s;
  }
  if (!(box.min_x() < box.max_x()) || !(box.min_y() < box.max_y())) {
    return Invalid(field + ": min (" + Num(box.min_x()) + ", " + Num(box.min_y()) +
                   ") must be below max (" + Num(box.max_x()) + ", " + Num(box.max_y()) + ")");
  }
  // Half-open, edges snapped to borders within a micro-cell (GridGeometry::CellsOfInterval).
  const GridGeometry::CellRange xs = g.CellsOfInterval(box.min_x(), box.max_x());
  const GridGeometry::CellRange ys = g.CellsOfInterval(box.min_y(), box.max_y());
  int64_t x0 = xs.first, y0 = ys.first, x1 = xs.last, y1 = ys.last;
  // Align pixel blocks with the global grid.
  const auto floor_to = [stride](int64_t a) {
    return (a >= 0 ? a / stride : -((-a + stride - 1) / stride)) * stride;
  };
  x0 = floor_to(x0);
  y0 = floor_to(y0);
  x1 = floor_to(x1) + stride - 1;
  y1 = floor_to(y1) + stride - 1;
  const int64_t w = x1 - x0 + 1, h = y1 - y0 + 1;
  // The limit counts what the server holds and sends: output pixels. The map cells behind them
  // are bounded apart (the time and the tiles a read costs).
  const uint64_t pw = static_cast<uint64_t>(w / stride), ph = static_cast<uint64_t>(h / stride);
  if (limit_cells && pw * ph > limits.max_region_cells) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            field + ": " + std::to_string(pw) + " x " + std::to_string(ph) + " = " +
                std::to_string(pw * ph) + " pixels at stride " + std::to_string(stride) +
                " exceed server.max_region_cells = " + std::to_string(limits.max_region_cells)};
  }
  const uint64_t cells = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  if (limit_cells && cells > limits.max_region_read_cells) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            field + ": " + std::to_string(w) + " x " + std::to_string(h) + " = " +
                std::to_string(cells) +
                " map cells to read exceed server.max_region_read_cells = " +
                std::to_string(limits.max_region_read_cells)};
  }
  out->min = {static_cast<int>(x0), static_cast<int>(y0)};
  out->max = {static_cast<int>(x1), static_cast<int>(y1)};
  return grpc::Status::OK;
}

}  // namespace bgkmap
