// Info: parameters, counts, bounds, version and per-robot progress.
#include <yaml-cpp/yaml.h>

#include <boost/asio/post.hpp>

#include "bgkmap/config/map_params_yaml.h"
#include "cluster/cluster_node.h"
#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"

namespace bgkmap {
namespace {

void ClusterToProto(const cluster::ClusterNode& node, v1::ClusterInfo* out) {
  const cluster::ClusterStatus s = node.Describe();
  out->set_node(s.node);
  for (const std::string& n : s.live_nodes) out->add_live_nodes(n);
  out->set_partitions(s.partitions_known);
  out->set_partition_tiles(static_cast<uint32_t>(node.layout().partition_tiles()));
  for (const cluster::ReplicaStats& r : s.replicas) {
    v1::PartitionInfo* p = out->add_owned();
    p->set_name(cluster::PartitionName(r.key));
    p->set_log_sequence(r.log_sequence);
    p->set_scans_integrated(r.scans_integrated);
    p->set_tiles(r.tiles);
    p->set_serving(r.serving);
    p->set_restored_from(r.restored_from);
  }
}

grpc::Status Info(ServiceContext& ctx, v1::InfoResponse* response) {
  const uint64_t version = ctx.reads.applied_version();
  if (ctx.cluster != nullptr) ClusterToProto(*ctx.cluster, response->mutable_cluster());
  const uint64_t applied = ctx.map.scans_applied();
  const MapSummary summary = ctx.map.Summary();
  ToProto(ctx.map.params(), response->mutable_params());
  YAML::Emitter yaml;
  yaml << MapParamsToYaml(ctx.map.params());
  response->set_params_yaml(std::string(yaml.c_str()) + "\n");
  response->set_tile_count(summary.tile_count);
  response->set_known_cells(summary.known_cells);
  ToProto(summary.known_bounds, response->mutable_known_cells_box());
  if (!summary.known_bounds.empty()) {
    const double r = ctx.map.geometry().resolution();
    v1::BoundingBox* b = response->mutable_known_bounds();
    b->set_min_x(summary.known_bounds.min.x * r);
    b->set_min_y(summary.known_bounds.min.y * r);
    b->set_max_x((summary.known_bounds.max.x + 1) * r);
    b->set_max_y((summary.known_bounds.max.y + 1) * r);
  }
  response->set_map_version(version);
  response->set_scans_applied(applied);
  for (const RobotProgress& r : ctx.map.robots().Robots()) {
    v1::RobotInfo* out = response->add_robots();
    out->set_robot_id(r.robot_id);
    out->set_last_sequence(r.last_sequence);
    out->mutable_last_stamp()->set_seconds(r.last_stamp.seconds);
    out->mutable_last_stamp()->set_nanos(r.last_stamp.nanos);
    out->set_scans_applied(r.scans_applied);
    out->set_scans_duplicate(r.scans_duplicate);
    out->set_scans_rejected(r.scans_rejected);
    out->set_points_kept(r.points_kept);
  }
  const ServerLimits& l = ctx.limits;
  v1::ServerLimits* lim = response->mutable_limits();
  lim->set_max_points_per_scan(l.max_points_per_scan);
  lim->set_max_region_cells(l.max_region_cells);
  lim->set_max_query_points(l.max_query_points);
  lim->set_max_path_poses(l.max_path_poses);
  lim->set_max_coordinate(l.max_coordinate);
  lim->set_max_message_bytes(l.max_message_bytes);
  lim->set_max_inflight_scans_per_stream(l.max_inflight_scans_per_stream);
  response->set_server_version(BGKMAP_VERSION);
  if (const storage::Georeference geo = ctx.map.georeference(); !geo.empty()) {
    v1::Georeference* g = response->mutable_georeference();
    g->set_crs(geo.crs);
    g->set_origin_easting(geo.origin[0]);
    g->set_origin_northing(geo.origin[1]);
    g->set_origin_height(geo.origin[2]);
  }
  const CorrectionStats c = ctx.map.corrections();
  v1::Corrections* corrections = response->mutable_corrections();
  corrections->set_in_progress(c.in_progress);
  corrections->set_applied(c.applied);
  corrections->set_failed(c.failed);
  corrections->set_scans_revised(c.scans_revised);
  corrections->set_records_replayed(c.records_replayed);
  corrections->set_last_seconds(c.last_seconds);
  if (const std::optional<StoreStatus> store = ctx.map.store_status()) {
    v1::StorageInfo* st = response->mutable_storage();
    st->set_data_dir(store->directory);
    st->set_durability(store->durability);
    st->set_checkpoint_version(store->checkpoint_version);
    st->set_corrupt_tiles(store->corrupt_tiles);
    const ResidencyStats r = ctx.map.Residency();
    st->set_memory_limit_bytes(ctx.config.storage.max_memory_mb << 20);
    st->set_resident_tiles(r.resident_tiles);
    st->set_resident_bytes(r.resident_bytes);
    st->set_tiles_loaded(r.tiles_loaded);
    st->set_tiles_evicted(r.tiles_evicted);
    st->set_writes_paused_for_space(store->writes_paused_for_space);
    st->set_read_only(store->read_only);
    st->set_free_bytes(store->free_bytes);
    st->set_free_space_reserve_bytes(store->reserve_bytes);
    st->set_writes_paused_reason(store->paused_reason);
  }
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* StartInfo(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                    PrincipalRef /*who*/, v1::InfoResponse* response) {
  // Answered on gRPC's thread: Info reads counters kept per change and takes no map-wide lock
  // (~0.2 ms), so a hop to the query pool would only add scheduling delay on a busy machine.
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (ctx.cluster != nullptr) {
    // A shard asks the log for its last sequence (a NATS round trip): not on gRPC's thread.
    boost::asio::post(ctx.query_pool,
                      [&ctx, response, reactor] { reactor->Finish(Info(ctx, response)); });
    return reactor;
  }
  reactor->Finish(Info(ctx, response));
  return reactor;
}

}  // namespace bgkmap
