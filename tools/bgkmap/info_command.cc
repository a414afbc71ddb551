// `bgkmap info`: the served map's parameters, size, bounds, version and robots, as JSON.
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "bgkmap/config/map_params_yaml.h"
#include "client_options.h"
#include "commands.h"
#include "robots_json.h"

namespace bgkmap::cli {
namespace {

// YAML scalars and sequences to JSON, keeping numbers numeric.
nlohmann::json ToJson(const YAML::Node& n) {
  if (n.IsSequence()) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& e : n) a.push_back(ToJson(e));
    return a;
  }
  if (n.IsMap()) {
    nlohmann::json o = nlohmann::json::object();
    for (const auto& e : n) o[e.first.as<std::string>()] = ToJson(e.second);
    return o;
  }
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    return n.as<std::string>();
  }
}

int RunInfo(const ServerTarget& server) {
  Result<std::unique_ptr<Client>> connected = Connect(server);
  if (!connected.ok()) return Usage("info", connected.status().message());
  Client& client = **connected;
  RpcResult<MapInfo> r = client.Info();
  if (!r.ok()) return Fail("info", r.status().ToString());
  const nlohmann::json robots = RobotsJson(r->robots);
  nlohmann::json out = {
      {"server_version", r->server_version},
      {"map_version", r->map_version},
      {"scans_applied", r->scans_applied},
      {"tile_count", r->tile_count},
      {"known_cells", r->known_cells},
      {"known_bounds", r->known_cells == 0 ? nlohmann::json(nullptr)
                                           : nlohmann::json{{"min_x", r->known_bounds.min_x},
                                                            {"min_y", r->known_bounds.min_y},
                                                            {"max_x", r->known_bounds.max_x},
                                                            {"max_y", r->known_bounds.max_y}}},
      {"params", ToJson(MapParamsToYaml(r->params))},
      {"robots", robots},
      {"limits",
       {{"max_points_per_scan", r->limits.max_points_per_scan},
        {"max_region_cells", r->limits.max_region_cells},
        {"max_region_read_cells", r->limits.max_region_read_cells},
        {"max_query_points", r->limits.max_query_points},
        {"max_path_poses", r->limits.max_path_poses},
        {"max_coordinate", r->limits.max_coordinate},
        {"max_message_bytes", r->limits.max_message_bytes}}}};
  out["georeference"] = nullptr;  // a local frame
  if (r->georeference.has_value()) {
    const std::array<double, 3>& o = r->georeference->origin;
    out["georeference"] = {{"crs", r->georeference->crs}, {"origin", {o[0], o[1], o[2]}}};
  }
  if (r->storage.has_value()) {
    const StorageInfo& st = *r->storage;
    out["storage"] = {{"data_dir", st.data_dir},
                      {"durability", st.durability},
                      {"checkpoint_version", st.checkpoint_version},
                      {"corrupt_tiles", st.corrupt_tiles},
                      {"memory_limit_bytes", st.memory_limit_bytes},
                      {"resident_tiles", st.resident_tiles},
                      {"resident_bytes", st.resident_bytes},
                      {"tiles_loaded", st.tiles_loaded},
                      {"tiles_evicted", st.tiles_evicted},
                      {"writes_paused_for_space", st.writes_paused_for_space},
                      {"read_only", st.read_only},
                      {"free_bytes", st.free_bytes},
                      {"free_space_reserve_bytes", st.free_space_reserve_bytes},
                      {"writes_paused_reason", st.writes_paused_reason}};
  }
  if (r->cluster.has_value()) {
    const ClusterInfo& c = *r->cluster;
    nlohmann::json owned = nlohmann::json::array();
    for (const ClusterPartitionInfo& p : c.owned) {
      owned.push_back({{"name", p.name},
                       {"log_sequence", p.log_sequence},
                       {"scans_integrated", p.scans_integrated},
                       {"tiles", p.tiles},
                       {"serving", p.serving},
                       {"restored_from", p.restored_from}});
    }
    out["cluster"] = {{"node", c.node},
                      {"live_nodes", c.live_nodes},
                      {"partitions", c.partitions},
                      {"partition_tiles", c.partition_tiles},
                      {"region_partitions", c.region_partitions},
                      {"nats_received_bytes", c.nats_received_bytes},
                      {"owned", owned}};
  }
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace

void RegisterInfoCommand(CLI::App& app, int& exit_code) {
  auto server = std::make_shared<ServerTarget>();
  CLI::App* cmd = app.add_subcommand("info", "Describe the served map (JSON)");
  AddServerOption(cmd, *server);
  cmd->callback([server, &exit_code] { exit_code = RunInfo(*server); });
}

}  // namespace bgkmap::cli
