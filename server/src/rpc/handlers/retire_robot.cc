// RetireRobot (admin): forgets a robot, so that an id invented by a client (or a robot that is
// gone) stops holding one of server.max_robots slots, also after a restart. Info lists robots.
#include <spdlog/spdlog.h>

#include "bgkmap/server/log_safe.h"
#include "rpc/handlers/handlers.h"

namespace bgkmap {

grpc::ServerUnaryReactor* StartRetireRobot(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::RetireRobotRequest* request,
                                           v1::RetireRobotResponse* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (ctx.sessions.draining()) {
    reactor->Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
    return reactor;
  }
  // Not CheckRobotId(): a store written before ids were checked may hold ids with control
  // characters, and those must be retirable too.
  const std::string& id = request->robot_id();
  if (id.empty()) {
    reactor->Finish({grpc::StatusCode::INVALID_ARGUMENT, "robot_id: must not be empty"});
    return reactor;
  }
  const std::string peer = call->peer();
  ctx.map.RetireRobot(id, [&ctx, reactor, response, peer, who](Result<RobotStats> retired) {
    if (!retired.ok()) {
      const Status& s = retired.status();
      if (s.code() == Status::Code::kFailedPrecondition) {
        reactor->Finish({grpc::StatusCode::NOT_FOUND, s.message()});
      } else {
        spdlog::error("event=retire_robot_failed reason=\"{}\"", LogSafe(s.message()));
        reactor->Finish({grpc::StatusCode::UNAVAILABLE, "robot not retired: " + s.message()});
      }
      return;
    }
    const size_t robots = ctx.map.Robots().size();
    spdlog::info("event=robot_retired robot=\"{}\" last_sequence={} robots={} peer=\"{}\"",
                 LogSafe(retired->robot_id, 128), retired->last_sequence, robots, LogSafe(peer));
    AuditLog(*who, "retire_robot", "robot=\"" + LogSafe(retired->robot_id, 128) + "\"",
             ctx.map.known_version(), peer);
    response->set_last_sequence(retired->last_sequence);
    response->set_robots(robots);
    reactor->Finish(grpc::Status::OK);
  });
  return reactor;
}

}  // namespace bgkmap
