#include "proto_codec.h"

#include <Eigen/Geometry>
#include <algorithm>

namespace bgkmap {

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

void ToProto(const MetricBox& box, v1::BoundingBox* out) {
  out->set_min_x(box.min_x);
  out->set_min_y(box.min_y);
  out->set_max_x(box.max_x);
  out->set_max_y(box.max_y);
}

MetricBox FromProto(const v1::BoundingBox& box) {
  return {box.min_x(), box.min_y(), box.max_x(), box.max_y()};
}

void ToProto(const ScanPose& in, v1::Pose3* pose) {
  pose->mutable_translation()->set_x(in.tx);
  pose->mutable_translation()->set_y(in.ty);
  pose->mutable_translation()->set_z(in.tz);
  pose->mutable_rotation()->set_w(in.qw);
  pose->mutable_rotation()->set_x(in.qx);
  pose->mutable_rotation()->set_y(in.qy);
  pose->mutable_rotation()->set_z(in.qz);
}

void ToProto(const ScanData& scan, v1::Scan* out) {
  out->set_robot_id(scan.robot_id);
  out->set_sequence(scan.sequence);
  out->mutable_stamp()->set_seconds(scan.stamp_ns / 1'000'000'000);
  out->mutable_stamp()->set_nanos(static_cast<int32_t>(scan.stamp_ns % 1'000'000'000));
  ToProto(scan.pose, out->mutable_pose());
  static_assert(sizeof(Point3f) == 12);
  out->mutable_points()->assign(reinterpret_cast<const char*>(scan.points.data()),
                                scan.points.size() * sizeof(Point3f));
}

void ToProto(const RegionQuery& query, v1::RegionRequest* out) {
  ToProto(query.box, out->mutable_box());
  for (Layer l : query.layers) out->add_layers(ToProto(l));
  out->set_stride(static_cast<uint32_t>(std::max(query.stride, 1)));
  out->set_compress(query.compress);
}

void ToProto(std::span<const std::array<double, 2>> points, const std::vector<Layer>& layers,
             v1::PointsRequest* out) {
  for (const auto& p : points) {
    v1::Point2* q = out->add_points();
    q->set_x(p[0]);
    q->set_y(p[1]);
  }
  for (Layer l : layers) out->add_layers(ToProto(l));
}

void ToProto(const PathQuery& query, v1::PathCheckRequest* out) {
  for (const Pose2& p : query.poses) {
    v1::Pose2* q = out->add_poses();
    q->set_x(p.x);
    q->set_y(p.y);
    q->set_yaw(p.yaw);
  }
  if (query.polygon.empty()) {
    out->set_radius(query.radius);
  } else {
    for (const auto& v : query.polygon) {
      v1::Point2* q = out->mutable_polygon()->add_vertices();
      q->set_x(v[0]);
      q->set_y(v[1]);
    }
  }
  if (query.max_traversability) out->set_max_traversability(*query.max_traversability);
  if (query.max_traversability_variance) {
    out->set_max_traversability_variance(*query.max_traversability_variance);
  }
  if (query.max_unknown_fraction) out->set_max_unknown_fraction(*query.max_unknown_fraction);
}

void ToProto(const WatchQuery& query, v1::WatchRequest* out) {
  ToProto(query.box, out->mutable_box());
  for (Layer l : query.layers) out->add_layers(ToProto(l));
  out->set_initial_snapshot(query.initial_snapshot);
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
  for (const v1::TileKey& k : a.changed_tiles()) ack.changed_tiles.push_back(FromProto(k));
  ack.map_version = a.map_version();
  ack.counts = FromProto(a.counts());
  return ack;
}

MapInfo FromProto(const v1::InfoResponse& r) {
  MapInfo info;
  info.params = FromProto(r.params());
  info.params_yaml = r.params_yaml();
  info.tile_count = r.tile_count();
  info.known_cells = r.known_cells();
  info.known_cells_box = FromProto(r.known_cells_box());
  info.known_bounds = FromProto(r.known_bounds());
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
                 l.max_inflight_scans_per_stream(),
                 l.max_region_read_cells()};
  info.server_version = r.server_version();
  if (r.has_storage()) {
    const v1::StorageInfo& s = r.storage();
    info.storage = StorageInfo{s.data_dir(),
                               s.durability(),
                               s.checkpoint_version(),
                               s.corrupt_tiles(),
                               s.memory_limit_bytes(),
                               s.resident_tiles(),
                               s.resident_bytes(),
                               s.tiles_loaded(),
                               s.tiles_evicted(),
                               s.writes_paused_for_space(),
                               s.read_only(),
                               s.free_bytes(),
                               s.free_space_reserve_bytes(),
                               s.writes_paused_reason()};
  }
  if (r.has_georeference()) {
    const v1::Georeference& g = r.georeference();
    info.georeference =
        Georeference{g.crs(), {g.origin_easting(), g.origin_northing(), g.origin_height()}};
  }
  if (r.has_cluster()) {
    const v1::ClusterInfo& c = r.cluster();
    ClusterInfo out{c.node(),
                    {c.live_nodes().begin(), c.live_nodes().end()},
                    c.partitions(),
                    c.partition_tiles(),
                    {},
                    c.region_partitions(),
                    c.nats_received_bytes()};
    for (const v1::PartitionInfo& p : c.owned()) {
      out.owned.push_back({p.name(), p.log_sequence(), p.scans_integrated(), p.tiles(), p.serving(),
                           p.restored_from()});
    }
    info.cluster = std::move(out);
  }
  return info;
}

PointValues FromProto(const v1::PointsResponse& response) {
  PointValues out;
  for (int l : response.layers()) out.layers.push_back(FromProto(static_cast<v1::Layer>(l)));
  out.values.assign(response.values().begin(), response.values().end());
  out.map_version = response.map_version();
  return out;
}

namespace {

PoseCheck FromProto(const v1::PoseCheck& pc) {
  return {pc.worst_traversability(), pc.worst_traversability_variance(), pc.unknown_fraction(),
          pc.cell_count(), pc.safe()};
}

PlacementCheck FromProto(const v1::PathPoint& p) {
  return {{{p.x(), p.y(), p.yaw()}, p.segment(), p.t()}, FromProto(p.check())};
}

}  // namespace

PathCheck FromProto(const v1::PathCheckResponse& response) {
  PathCheck out;
  for (const v1::PoseCheck& pc : response.poses()) out.poses.push_back(FromProto(pc));
  for (const v1::SegmentCheck& sc : response.segments()) {
    SegmentCheck& segment = out.segments.emplace_back();
    segment.safe = sc.safe();
    segment.placement_count = sc.placement_count();
    if (sc.has_first_unsafe()) segment.first_unsafe = FromProto(sc.first_unsafe());
  }
  out.safe = response.safe();
  out.first_unsafe_index = response.first_unsafe_index();
  if (response.has_first_unsafe_point())
    out.first_unsafe = FromProto(response.first_unsafe_point());
  out.map_version = response.map_version();
  return out;
}

TileUpdate FromProto(const v1::TileUpdate& message) {
  TileUpdate update;
  update.key = FromProto(message.key());
  update.tile_version = message.tile_version();
  update.map_version = message.map_version();
  update.raster = TileRasterFromProto(message);
  return update;
}

ClearResult FromProto(const v1::ClearRegionResponse& response) {
  ClearResult out;
  for (const v1::TileKey& k : response.changed_tiles()) out.changed_tiles.push_back(FromProto(k));
  out.map_version = response.map_version();
  return out;
}

ImportResult FromProto(const v1::ImportResponse& response) {
  ImportResult result;
  result.tiles_added = response.tiles_added();
  result.map_version = response.map_version();
  result.known_cells = response.known_cells();
  result.archive_map_version = response.archive_map_version();
  return result;
}

}  // namespace client_codec
}  // namespace bgkmap
