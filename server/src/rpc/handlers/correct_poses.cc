// CorrectPoses and RemoveScans: a robot's SLAM revised its trajectory (or its scans are bad);
// the map re-integrates them in the background (MapWrites::SubmitCorrection).
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <set>

#include "bgkmap/server/log_safe.h"
#include "rpc/access_control.h"
#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

grpc::Status CorrectionStatus(const Status& s) {
  if (s.code() == Status::Code::kIoError) {
    return {grpc::StatusCode::UNAVAILABLE, "nothing changed: " + s.message()};
  }
  return ToGrpcStatus(s);
}

// Checks shared by both calls; OK to go on.
grpc::Status Admissible(ServiceContext& ctx, const Principal& who, const std::string& robot_id) {
  if (ctx.sessions.draining()) return {grpc::StatusCode::UNAVAILABLE, "server is shutting down"};
  if (grpc::Status s = CheckRobotId(robot_id); !s.ok()) return s;
  if (!who.MayIngestAs(robot_id)) return NotThisRobot(who, robot_id);
  const std::vector<RobotStats> robots = ctx.map.Robots();
  const bool known = std::any_of(robots.begin(), robots.end(),
                                 [&](const RobotStats& r) { return r.robot_id == robot_id; });
  if (!known) {
    return {grpc::StatusCode::NOT_FOUND, "robot_id: '" + robot_id + "' is not a known robot"};
  }
  return grpc::Status::OK;
}

// A token runs one correction at a time (issue 25: 20 at once from one robot token delayed
// another robot's acks by 27.5 s). The permit is held until the correction is answered.
constexpr uint32_t kCorrectionsPerToken = 1;

template <typename Response>
void Submit(ServiceContext& ctx, grpc::ServerUnaryReactor* reactor, PrincipalRef who,
            const std::string& peer, CorrectionSpec spec, Response* response, const char* action) {
  std::shared_ptr<Permit> permit;
  if (who->usage != nullptr) {
    permit = std::make_shared<Permit>(who->usage->corrections, kCorrectionsPerToken);
    if (!*permit) {
      reactor->Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
                       "token '" + who->name +
                           "' already has a correction running (one at a time per token); "
                           "retry once it is answered"});
      return;
    }
  }
  const std::string robot = spec.robot_id;
  auto done = [reactor, response, peer, who = std::move(who), robot, action,
               permit = std::move(permit)](CorrectionOutcome outcome) mutable {
    permit.reset();  // before the answer: the token's next correction may follow at once
    if (!outcome.status.ok()) {
      spdlog::warn("event={}_refused robot=\"{}\" reason=\"{}\"", action, LogSafe(robot, 128),
                   LogSafe(outcome.status.message()));
      reactor->Finish(CorrectionStatus(outcome.status));
      return;
    }
    spdlog::info(
        "event={} robot=\"{}\" scans={} records_replayed={} records_in_history={} tiles={} "
        "version={} seconds={:.3f}",
        action, LogSafe(robot, 128), outcome.scans_revised, outcome.records_replayed,
        outcome.records_in_history, outcome.changed_tiles.size(), outcome.version, outcome.seconds);
    AuditLog(*who, action, "robot=\"" + LogSafe(robot, 128) + "\"", outcome.version, peer);
    v1::CorrectionSummary* summary = response->mutable_summary();
    summary->set_map_version(outcome.version);
    summary->set_scans_revised(outcome.scans_revised);
    summary->set_records_replayed(outcome.records_replayed);
    summary->set_records_in_history(outcome.records_in_history);
    summary->set_tiles_changed(outcome.changed_tiles.size());
    summary->set_seconds(outcome.seconds);
    reactor->Finish(grpc::Status::OK);
  };
  // Planning reads the retained log and prepares the revised scans again: not on gRPC's thread.
  boost::asio::post(ctx.query_pool,
                    [&ctx, spec = std::move(spec), done = std::move(done)]() mutable {
                      ctx.map.SubmitCorrection(std::move(spec), std::move(done));
                    });
}

}  // namespace

grpc::ServerUnaryReactor* StartCorrectPoses(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                            PrincipalRef who,
                                            const v1::CorrectPosesRequest* request,
                                            v1::CorrectPosesResponse* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (grpc::Status s = Admissible(ctx, *who, request->robot_id()); !s.ok()) {
    reactor->Finish(s);
    return reactor;
  }
  const int n = request->corrections_size();
  if (n == 0) {
    reactor->Finish({grpc::StatusCode::INVALID_ARGUMENT, "corrections: empty"});
    return reactor;
  }
  if (static_cast<uint64_t>(n) > ctx.limits.max_points_per_scan) {
    reactor->Finish(
        {grpc::StatusCode::INVALID_ARGUMENT, "corrections: " + std::to_string(n) +
                                                 " entries exceed server.max_points_per_scan = " +
                                                 std::to_string(ctx.limits.max_points_per_scan)});
    return reactor;
  }
  CorrectionSpec spec;
  spec.robot_id = request->robot_id();
  for (int i = 0; i < n; ++i) {
    const v1::PoseCorrection& c = request->corrections(i);
    const std::string field = "corrections[" + std::to_string(i) + "]";
    if (!c.has_pose()) {
      reactor->Finish({grpc::StatusCode::INVALID_ARGUMENT, field + ".pose: missing"});
      return reactor;
    }
    Pose pose;
    if (grpc::Status s = CheckPose(c.pose(), ctx.map.params(), ctx.limits, &pose); !s.ok()) {
      reactor->Finish({s.error_code(), field + "." + s.error_message()});
      return reactor;
    }
    if (!spec.poses.emplace(c.sequence(), pose).second) {
      reactor->Finish({grpc::StatusCode::INVALID_ARGUMENT,
                       field + ".sequence: " + std::to_string(c.sequence()) +
                           " is listed twice; each scan may be corrected once per request"});
      return reactor;
    }
  }
  Submit(ctx, reactor, who, call->peer(), std::move(spec), response, "poses_corrected");
  return reactor;
}

grpc::ServerUnaryReactor* StartRemoveScans(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::RemoveScansRequest* request,
                                           v1::RemoveScansResponse* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (grpc::Status s = Admissible(ctx, *who, request->robot_id()); !s.ok()) {
    reactor->Finish(s);
    return reactor;
  }
  if (request->first_sequence() > request->last_sequence()) {
    reactor->Finish({grpc::StatusCode::INVALID_ARGUMENT,
                     "first_sequence: " + std::to_string(request->first_sequence()) +
                         " is above last_sequence " + std::to_string(request->last_sequence())});
    return reactor;
  }
  CorrectionSpec spec;
  spec.robot_id = request->robot_id();
  spec.remove = {request->first_sequence(), request->last_sequence()};
  Submit(ctx, reactor, who, call->peer(), std::move(spec), response, "scans_removed");
  return reactor;
}

}  // namespace bgkmap
