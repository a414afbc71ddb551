// Info: parameters, counts, bounds, version and per-robot progress.
#include <yaml-cpp/yaml.h>

#include "bgkmap/config/map_params_yaml.h"
#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"

namespace bgkmap {
namespace {

void ShardToProto(const ShardState& shard, v1::ClusterInfo* out) {
  out->set_node(shard.node);
  for (const std::string& n : shard.live_nodes) out->add_live_nodes(n);
  out->set_partitions(shard.partitions_known);
  out->set_partition_tiles(shard.partition_tiles);
  out->set_region_partitions(shard.region_partitions);
  out->set_nats_received_bytes(shard.nats_received_bytes);
  for (const ShardState::Partition& r : shard.owned) {
    v1::PartitionInfo* p = out->add_owned();
    p->set_name(r.name);
    p->set_log_sequence(r.log_sequence);
    p->set_scans_integrated(r.scans_integrated);
    p->set_tiles(r.tiles);
    p->set_serving(r.serving);
    p->set_restored_from(r.restored_from);
  }
}

void StorageToProto(const StorageState& store, uint64_t memory_limit_bytes, v1::StorageInfo* st) {
  st->set_data_dir(store.directory);
  st->set_durability(store.durability);
  st->set_checkpoint_version(store.checkpoint_version);
  st->set_corrupt_tiles(store.corrupt_tiles);
  st->set_memory_limit_bytes(memory_limit_bytes);
  st->set_resident_tiles(store.residency.resident_tiles);
  st->set_resident_bytes(store.residency.resident_bytes);
  st->set_tiles_loaded(store.residency.tiles_loaded);
  st->set_tiles_evicted(store.residency.tiles_evicted);
  st->set_writes_paused_for_space(store.writes_paused_for_space);
  st->set_read_only(store.read_only);
  st->set_free_bytes(store.free_bytes);
  st->set_free_space_reserve_bytes(store.reserve_bytes);
  st->set_writes_paused_reason(store.paused_reason);
}

void RobotsToProto(const std::vector<RobotStats>& robots, v1::InfoResponse* response) {
  for (const RobotStats& r : robots) {
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
}

void LimitsToProto(const ServerLimits& l, v1::ServerLimits* lim) {
  lim->set_max_points_per_scan(l.max_points_per_scan);
  lim->set_max_region_cells(l.max_region_cells);
  lim->set_max_query_points(l.max_query_points);
  lim->set_max_path_poses(l.max_path_poses);
  lim->set_max_coordinate(l.max_coordinate);
  lim->set_max_message_bytes(l.max_message_bytes);
  lim->set_max_inflight_scans_per_stream(l.max_inflight_scans_per_stream);
  lim->set_max_region_read_cells(l.max_region_read_cells);
}

void CorrectionsToProto(const CorrectionStats& c, v1::Corrections* corrections) {
  corrections->set_in_progress(c.in_progress);
  corrections->set_applied(c.applied);
  corrections->set_failed(c.failed);
  corrections->set_scans_revised(c.scans_revised);
  corrections->set_records_replayed(c.records_replayed);
  corrections->set_last_seconds(c.last_seconds);
}

grpc::Status Info(ServiceContext& ctx, uint64_t version, v1::InfoResponse* response) {
  const MapState state = ctx.map.State();
  if (state.shard) ShardToProto(*state.shard, response->mutable_cluster());
  ToProto(ctx.map.params(), response->mutable_params());
  YAML::Emitter yaml;
  yaml << MapParamsToYaml(ctx.map.params());
  response->set_params_yaml(std::string(yaml.c_str()) + "\n");
  const MapSummary& summary = state.summary;
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
  response->set_scans_applied(state.scans_applied);
  RobotsToProto(state.robots, response);
  LimitsToProto(ctx.limits, response->mutable_limits());
  response->set_server_version(BGKMAP_VERSION);
  if (const Georeference& geo = state.georeference; !geo.empty()) {
    v1::Georeference* g = response->mutable_georeference();
    g->set_crs(geo.crs);
    g->set_origin_easting(geo.origin[0]);
    g->set_origin_northing(geo.origin[1]);
    g->set_origin_height(geo.origin[2]);
  }
  CorrectionsToProto(state.corrections, response->mutable_corrections());
  if (state.storage) {
    StorageToProto(*state.storage, ctx.config.storage.max_memory_mb << 20,
                   response->mutable_storage());
  }
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* StartInfo(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                    PrincipalRef /*who*/, v1::InfoResponse* response) {
  // Answered on gRPC's thread when the map has its version at hand: Info reads counters kept
  // per change and takes no map-wide lock (~0.2 ms), so a hop to the query pool would only add
  // scheduling delay on a busy machine. A map that must ask for its version (a cluster node,
  // its log) answers on a worker of its own.
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  ctx.map.ReadVersion([&ctx, response, reactor](uint64_t version) {
    reactor->Finish(Info(ctx, version, response));
  });
  return reactor;
}

}  // namespace bgkmap
