#include "proto_codec.h"

#include <Eigen/Geometry>
#include <bit>
#include <cstring>

namespace bgkmap {

static_assert(std::endian::native == std::endian::little,
              "packed float32 payloads are little-endian; add byte swapping for this host");

ScanPose ScanPose::FromPose(const Pose& pose) {
  Eigen::Quaterniond q(pose.rotation);
  q.normalize();
  ScanPose p;
  p.tx = pose.translation.x();
  p.ty = pose.translation.y();
  p.tz = pose.translation.z();
  p.qw = q.w();
  p.qx = q.x();
  p.qy = q.y();
  p.qz = q.z();
  return p;
}

const RobotInfo* MapInfo::FindRobot(const std::string& id) const {
  for (const RobotInfo& r : robots) {
    if (r.robot_id == id) return &r;
  }
  return nullptr;
}

namespace client_codec {

RpcStatus FromGrpc(const grpc::Status& status) {
  return RpcStatus(static_cast<RpcCode>(status.error_code()), status.error_message());
}

v1::Layer ToProto(Layer layer) { return static_cast<v1::Layer>(static_cast<int>(layer) + 1); }
Layer FromProto(v1::Layer layer) { return static_cast<Layer>(static_cast<int>(layer) - 1); }

void ToProto(const MetricBox& box, v1::BoundingBox* out) {
  out->set_min_x(box.min_x);
  out->set_min_y(box.min_y);
  out->set_max_x(box.max_x);
  out->set_max_y(box.max_y);
}

void ToProto(const ScanData& scan, v1::Scan* out) {
  out->set_robot_id(scan.robot_id);
  out->set_sequence(scan.sequence);
  out->mutable_stamp()->set_seconds(scan.stamp_ns / 1'000'000'000);
  out->mutable_stamp()->set_nanos(static_cast<int32_t>(scan.stamp_ns % 1'000'000'000));
  v1::Pose3* pose = out->mutable_pose();
  pose->mutable_translation()->set_x(scan.pose.tx);
  pose->mutable_translation()->set_y(scan.pose.ty);
  pose->mutable_translation()->set_z(scan.pose.tz);
  pose->mutable_rotation()->set_w(scan.pose.qw);
  pose->mutable_rotation()->set_x(scan.pose.qx);
  pose->mutable_rotation()->set_y(scan.pose.qy);
  pose->mutable_rotation()->set_z(scan.pose.qz);
  static_assert(sizeof(Point3f) == 12);
  out->mutable_points()->assign(reinterpret_cast<const char*>(scan.points.data()),
                                scan.points.size() * sizeof(Point3f));
}

CellBox FromProto(const v1::CellBox& box) {
  return {{box.min_x(), box.min_y()}, {box.max_x(), box.max_y()}};
}

ScanAck FromProto(const v1::ScanAck& a) {
  ScanAck ack;
  ack.robot_id = a.robot_id();
  ack.sequence = a.sequence();
  switch (a.status()) {
    case v1::ACK_APPLIED:
      ack.status = AckStatus::kApplied;
      break;
    case v1::ACK_DUPLICATE:
      ack.status = AckStatus::kDuplicate;
      break;
    default:
      ack.status = AckStatus::kRejected;
      break;
  }
  ack.error = RpcStatus(static_cast<RpcCode>(a.code()), a.message());
  for (const v1::TileKey& k : a.changed_tiles()) ack.changed_tiles.push_back({k.x(), k.y()});
  ack.map_version = a.map_version();
  const v1::PointCounts& c = a.counts();
  ack.counts.input = c.input();
  ack.counts.kept = c.kept();
  ack.counts.dropped_nonfinite = c.dropped_nonfinite();
  ack.counts.dropped_range = c.dropped_range();
  ack.counts.dropped_height = c.dropped_height();
  ack.counts.dropped_out_of_bounds = c.dropped_out_of_bounds();
  return ack;
}

MapInfo FromProto(const v1::InfoResponse& r) {
  MapInfo info;
  const v1::MapParameters& p = r.params();
  MapParams& m = info.params;
  m.resolution = p.resolution();
  m.kernel_length = p.kernel_length();
  m.lambda = p.lambda();
  m.prior_mean = p.prior_mean();
  m.sigma2 = p.sigma2();
  m.alpha0 = p.alpha0();
  m.beta0 = p.beta0();
  m.robot_radius = p.robot_radius();
  m.step_crit = p.step_crit();
  m.slope_crit_deg = p.slope_crit_deg();
  m.roughness_crit = p.roughness_crit();
  for (int i = 0; i < 3 && i < p.weights_size(); ++i) m.weights[i] = p.weights(i);
  m.trav_threshold = p.trav_threshold();
  m.variance_threshold = p.variance_threshold();
  m.min_range = p.min_range();
  m.max_range = p.max_range();
  m.max_height_above_sensor = p.max_height_above_sensor();
  if (Result<Observation> o = ParseObservation(p.observation()); o.ok()) m.observation = *o;
  m.tile_size = p.tile_size();
  if (Result<Method> meth = ParseMethod(p.method()); meth.ok()) m.method = *meth;
  info.params_yaml = r.params_yaml();
  info.tile_count = r.tile_count();
  info.known_cells = r.known_cells();
  info.known_cells_box = FromProto(r.known_cells_box());
  info.known_bounds = {r.known_bounds().min_x(), r.known_bounds().min_y(), r.known_bounds().max_x(),
                       r.known_bounds().max_y()};
  info.map_version = r.map_version();
  info.scans_applied = r.scans_applied();
  for (const v1::RobotInfo& ri : r.robots()) {
    RobotInfo robot;
    robot.robot_id = ri.robot_id();
    robot.last_sequence = ri.last_sequence();
    robot.last_stamp_ns = ri.last_stamp().seconds() * 1'000'000'000 + ri.last_stamp().nanos();
    robot.scans_applied = ri.scans_applied();
    robot.scans_duplicate = ri.scans_duplicate();
    robot.scans_rejected = ri.scans_rejected();
    robot.points_kept = ri.points_kept();
    info.robots.push_back(std::move(robot));
  }
  const v1::ServerLimits& l = r.limits();
  info.limits = {l.max_points_per_scan(),
                 l.max_region_cells(),
                 l.max_query_points(),
                 l.max_path_poses(),
                 l.max_coordinate(),
                 l.max_message_bytes(),
                 l.max_inflight_scans_per_stream()};
  info.server_version = r.server_version();
  if (r.has_storage()) {
    const v1::StorageInfo& s = r.storage();
    info.storage = StorageInfo{s.data_dir(),       s.durability(),         s.checkpoint_version(),
                               s.corrupt_tiles(),  s.memory_limit_bytes(), s.resident_tiles(),
                               s.resident_bytes(), s.tiles_loaded(),       s.tiles_evicted()};
  }
  return info;
}

bool UnpackFloats(const std::string& bytes, std::vector<float>* out) {
  if (bytes.size() % sizeof(float) != 0) return false;
  out->resize(bytes.size() / sizeof(float));
  if (!bytes.empty()) std::memcpy(out->data(), bytes.data(), bytes.size());
  return true;
}

}  // namespace client_codec
}  // namespace bgkmap
