// `bgkmap robots`: the robots the server knows, as JSON; `bgkmap retire-robot ID --yes`: forget
// one (admin), e.g. an id a client invented or a robot whose sequence numbers went wrong.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "client_options.h"
#include "commands.h"
#include "robots_json.h"

namespace bgkmap::cli {
namespace {

int RunRobots(const ServerTarget& server) {
  Result<std::unique_ptr<Client>> connected = Connect(server);
  if (!connected.ok()) return Usage("robots", connected.status().message());
  Client& client = **connected;
  RpcResult<MapInfo> r = client.Info();
  if (!r.ok()) return Fail("robots", r.status().ToString());
  const nlohmann::json robots = RobotsJson(r->robots);
  std::printf("%s\n", robots.dump(2, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
  return 0;
}

struct RetireOptions {
  ServerTarget server;
  std::string robot_id;
  bool yes = false;
};

int RunRetire(const RetireOptions& o) {
  if (!o.yes) {
    return Usage("retire-robot",
                 "the robot's sequence number is forgotten (its next scan starts afresh); pass "
                 "--yes to confirm");
  }
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("retire-robot", connected.status().message());
  Client& client = **connected;
  RpcResult<RetiredRobot> r = client.RetireRobot(o.robot_id);
  if (!r.ok()) return Fail("retire-robot", r.status().ToString());
  std::printf("bgkmap retire-robot: retired at sequence %llu; %llu robots left\n",
              static_cast<unsigned long long>(r->last_sequence),
              static_cast<unsigned long long>(r->robots));
  return 0;
}

}  // namespace

void RegisterRobotsCommand(CLI::App& app, int& exit_code) {
  auto server = std::make_shared<ServerTarget>();
  CLI::App* cmd = app.add_subcommand("robots", "List the robots the server knows (JSON)");
  AddServerOption(cmd, *server);
  cmd->callback([server, &exit_code] { exit_code = RunRobots(*server); });
}

void RegisterRetireRobotCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<RetireOptions>();
  CLI::App* cmd = app.add_subcommand("retire-robot",
                                     "Forget a robot: its next scan starts a new sequence (admin)");
  AddServerOption(cmd, o->server);
  cmd->add_option("robot_id", o->robot_id, "The robot's id (bgkmap robots lists them)")->required();
  cmd->add_flag("--yes", o->yes, "Confirm");
  cmd->callback([o, &exit_code] { exit_code = RunRetire(*o); });
}

}  // namespace bgkmap::cli
