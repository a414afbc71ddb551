// `bgkmap check-path`: is a path safe for a robot of this footprint, at its poses and along the
// segments between them? JSON per pose and segment, with the first unsafe point; exit code 0
// when safe, 1 when not, 2 on any error (like grep and diff, so scripts can branch on it).
#include <cstdio>
#include <nlohmann/json.hpp>

#include "client_options.h"
#include "commands.h"
#include "json_output.h"

namespace bgkmap::cli {
namespace {

struct CheckPathOptions {
  ServerTarget server;
  std::vector<double> poses;    // x,y,yaw triples
  std::vector<double> polygon;  // x,y pairs, robot frame
  double radius = 0;
  double max_trav = -1, max_var = -1, max_unknown = -1;
};

// Any error of check-path, usage or failure, exits kExitCheckError (2); 1 means unsafe.
int Error(const std::string& message) {
  Fail("check-path", message);
  return kExitCheckError;
}

nlohmann::json CheckJson(const PoseCheck& c) {
  return {{"worst_traversability", JsonNumber(c.worst_traversability)},
          {"worst_traversability_variance", JsonNumber(c.worst_traversability_variance)},
          {"unknown_fraction", c.unknown_fraction},
          {"cells", c.cell_count},
          {"safe", c.safe}};
}

nlohmann::json PlacementJson(const PlacementCheck& p) {
  nlohmann::json out = {{"x", p.where.pose.x},
                        {"y", p.where.pose.y},
                        {"yaw", p.where.pose.yaw},
                        {"segment", p.where.segment},
                        {"t", p.where.t}};
  out.update(CheckJson(p.check));
  return out;
}

int RunCheckPath(const CheckPathOptions& o) {
  if (o.poses.empty() || o.poses.size() % 3 != 0) {
    return Error("--poses: expected x,y,yaw triples");
  }
  if (!o.polygon.empty() && o.polygon.size() % 2 != 0) {
    return Error("--polygon: expected x,y pairs");
  }
  if (o.polygon.empty() && !(o.radius > 0)) {
    return Error("give a footprint: --radius R or --polygon x,y,...");
  }
  PathQuery q;
  for (size_t i = 0; i < o.poses.size(); i += 3) {
    q.poses.push_back({o.poses[i], o.poses[i + 1], o.poses[i + 2]});
  }
  for (size_t i = 0; i < o.polygon.size(); i += 2)
    q.polygon.push_back({o.polygon[i], o.polygon[i + 1]});
  q.radius = o.radius;
  if (o.max_trav >= 0) q.max_traversability = o.max_trav;
  if (o.max_var >= 0) q.max_traversability_variance = o.max_var;
  if (o.max_unknown >= 0) q.max_unknown_fraction = o.max_unknown;
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Error(connected.status().message());
  Client& client = **connected;
  RpcResult<PathCheck> r = client.CheckPath(q);
  if (!r.ok()) return Error(r.status().ToString());
  nlohmann::json out = {{"safe", r->safe},
                        {"first_unsafe_index", r->first_unsafe_index},
                        {"map_version", r->map_version},
                        {"poses", nlohmann::json::array()}};
  for (size_t i = 0; i < r->poses.size(); ++i) {
    const PoseCheck& c = r->poses[i];
    nlohmann::json pose = {{"x", q.poses[i].x}, {"y", q.poses[i].y}, {"yaw", q.poses[i].yaw}};
    pose.update(CheckJson(c));
    out["poses"].push_back(std::move(pose));
  }
  // Where the path first fails: at a pose (t = 0) or between poses[segment] and the next.
  out["first_unsafe_point"] = nullptr;
  if (r->first_unsafe) out["first_unsafe_point"] = PlacementJson(*r->first_unsafe);
  out["segments"] = nlohmann::json::array();
  for (const SegmentCheck& s : r->segments) {
    out["segments"].push_back({{"safe", s.safe}, {"placements", s.placement_count}});
  }
  std::printf("%s\n", out.dump(2).c_str());
  return r->safe ? kExitOk : kExitUnsafe;
}

}  // namespace

void RegisterCheckPathCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<CheckPathOptions>();
  CLI::App* cmd = app.add_subcommand(
      "check-path",
      "Check a path, its poses and the straight segments between them, against the map (JSON; "
      "exit 0 safe, 1 unsafe, 2 error)");
  AddServerOption(cmd, o->server);
  cmd->add_option("--poses", o->poses, "x,y,yaw,x,y,yaw,... (metres, radians)")
      ->delimiter(',')
      ->required();
  cmd->add_option("--radius", o->radius, "Disk footprint radius, metres");
  cmd->add_option("--polygon", o->polygon, "Footprint polygon in the robot frame: x,y,x,y,...")
      ->delimiter(',');
  cmd->add_option("--max-traversability", o->max_trav, "Default: the map's trav_threshold");
  cmd->add_option("--max-variance", o->max_var, "Default: the map's variance_threshold");
  cmd->add_option("--max-unknown", o->max_unknown, "Largest unknown fraction (default 0)");
  cmd->callback([o, &exit_code] { exit_code = RunCheckPath(*o); });
}

}  // namespace bgkmap::cli
