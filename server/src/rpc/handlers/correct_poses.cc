// CorrectPoses and RemoveScans: a robot's SLAM revised its trajectory (or its scans are bad);
// the map re-integrates them in the background (MapWrites::SubmitCorrection).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/post.hpp>
#include <memory>

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

// Checks shared by both calls; OK to go on. `last_sequence`: the robot's last one.
grpc::Status Admissible(ServiceContext& ctx, const Principal& who, const std::string& robot_id,
                        uint64_t* last_sequence) {
  if (ctx.sessions.draining()) return {grpc::StatusCode::UNAVAILABLE, "server is shutting down"};
  if (grpc::Status s = CheckRobotId(robot_id); !s.ok()) return s;
  if (!who.MayIngestAs(robot_id)) return NotThisRobot(who, robot_id);
  const std::vector<RobotStats> robots = ctx.map.Robots();
  const auto robot = std::find_if(robots.begin(), robots.end(),
                                  [&](const RobotStats& r) { return r.robot_id == robot_id; });
  if (robot == robots.end()) {
    return {grpc::StatusCode::NOT_FOUND, "robot_id: '" + robot_id + "' is not a known robot"};
  }
  *last_sequence = robot->last_sequence;
  return grpc::Status::OK;
}

// A token runs one correction at a time (issue 25: 20 at once from one robot token delayed
// another robot's acks by 27.5 s). The permit is held until the correction is answered.
constexpr uint32_t kCorrectionsPerToken = 1;

// The token's correction permit (null without authentication), or the refusal in `refusal`.
std::shared_ptr<Permit> CorrectionPermit(const Principal& who, grpc::Status* refusal) {
  if (who.usage == nullptr) return nullptr;
  auto permit = std::make_shared<Permit>(who.usage->corrections, kCorrectionsPerToken);
  if (!*permit) {
    *refusal = {grpc::StatusCode::RESOURCE_EXHAUSTED,
                "token '" + who.name +
                    "' already has a correction running (one at a time per token); retry once "
                    "it is answered"};
  }
  return permit;
}

// The largest encoding of one CorrectPosesRequest entry: its tag and length (2), the sequence
// (1 + 10) and the pose (2 + translation 29 + rotation 38). A request of n entries is at most
// n times this plus kRequestSlackBytes (the robot id and framing).
constexpr uint64_t kMaxEntryBytes = 82;
constexpr uint64_t kRequestSlackBytes = 4096;

// One correction's call (both RPCs): answered when the correction is, or dropped, nothing
// changed, if the client cancels first (a deadline, TryCancel, a closed connection: OnCancel).
// CorrectPoses is served raw, so that the request's size is judged before protobuf builds it
// (issue 25: a 2M-entry request cost ~650 MB before it was refused); the call owns the parsed
// request and the response, serialized into the raw answer.
class CorrectionCall final : public grpc::ServerUnaryReactor {
 public:
  // `raw_answer`: CorrectPoses' serialized response; null for RemoveScans (typed).
  explicit CorrectionCall(grpc::ByteBuffer* raw_answer) : raw_answer_(raw_answer) {}

  std::shared_ptr<const std::atomic<bool>> cancelled() const { return cancelled_; }
  v1::CorrectPosesRequest request;
  v1::CorrectPosesResponse response;

  // Finishes with `status`; an OK CorrectPoses answer serializes `response` first.
  void Answer(const grpc::Status& status) {
    if (status.ok() && raw_answer_ != nullptr) {
      bool own = false;
      grpc::Status encoded = grpc::SerializationTraits<v1::CorrectPosesResponse>::Serialize(
          response, raw_answer_, &own);
      if (!encoded.ok()) return Finish(encoded);
    }
    Finish(status);
  }

  void OnCancel() override { cancelled_->store(true); }
  void OnDone() override { delete this; }

 private:
  grpc::ByteBuffer* raw_answer_;
  std::shared_ptr<std::atomic<bool>> cancelled_ = std::make_shared<std::atomic<bool>>(false);
};

void SummaryToProto(const CorrectionOutcome& outcome, v1::CorrectionSummary* summary) {
  summary->set_map_version(outcome.version);
  summary->set_scans_revised(outcome.scans_revised);
  summary->set_records_replayed(outcome.records_replayed);
  summary->set_records_in_history(outcome.records_in_history);
  summary->set_tiles_changed(outcome.changed_tiles.size());
  summary->set_seconds(outcome.seconds);
}

// Queues `spec` on the map and answers `call` when it is done; `summary` is filled on success.
void Submit(ServiceContext& ctx, CorrectionCall* call, PrincipalRef who, const std::string& peer,
            std::shared_ptr<Permit> permit, CorrectionSpec spec, v1::CorrectionSummary* summary,
            const char* action) {
  spec.cancelled = call->cancelled();
  const std::string robot = spec.robot_id;
  auto done = [call, summary, peer, who = std::move(who), robot, action,
               permit = std::move(permit)](CorrectionOutcome outcome) mutable {
    permit.reset();  // before the answer: the token's next correction may follow at once
    if (!outcome.status.ok()) {
      spdlog::warn("event={}_refused robot=\"{}\" reason=\"{}\"", action, LogSafe(robot, 128),
                   LogSafe(outcome.status.message()));
      call->Answer(CorrectionStatus(outcome.status));
      return;
    }
    spdlog::info(
        "event={} robot=\"{}\" scans={} records_replayed={} records_in_history={} tiles={} "
        "version={} seconds={:.3f}",
        action, LogSafe(robot, 128), outcome.scans_revised, outcome.records_replayed,
        outcome.records_in_history, outcome.changed_tiles.size(), outcome.version, outcome.seconds);
    AuditLog(*who, action, "robot=\"" + LogSafe(robot, 128) + "\"", outcome.version, peer);
    SummaryToProto(outcome, summary);
    call->Answer(grpc::Status::OK);
  };
  // Planning reads the retained log and prepares the revised scans again: not on gRPC's thread.
  boost::asio::post(ctx.query_pool,
                    [&ctx, spec = std::move(spec), done = std::move(done)]() mutable {
                      ctx.map.SubmitCorrection(std::move(spec), std::move(done));
                    });
}

// The request's bytes against the most entries any correction may name now (min of
// server.max_correction_scans and the retained log's records), before it is parsed.
grpc::Status CheckRequestBytes(const ServiceContext& ctx, const grpc::ByteBuffer& raw) {
  const uint64_t retained = ctx.map.retained_records_bound();
  const uint64_t entries = std::min(ctx.limits.max_correction_scans, retained);
  const uint64_t cap = entries * kMaxEntryBytes + kRequestSlackBytes;
  const uint64_t bytes = raw.Length();
  if (bytes <= cap) return grpc::Status::OK;
  return {grpc::StatusCode::INVALID_ARGUMENT,
          "request: " + std::to_string(bytes) +
              " bytes, more than a correction can name (at most " + std::to_string(cap) +
              " bytes: " + std::to_string(retained) +
              " retained scans, server.max_correction_scans = " +
              std::to_string(ctx.limits.max_correction_scans) + ", " +
              std::to_string(kMaxEntryBytes) + " bytes an entry)"};
}

// The entry count against server.max_correction_scans and the robot's retained scans (at most
// the retained log's records, and its sequence numbers up to its last), before any is read.
grpc::Status CheckEntryCount(const ServiceContext& ctx, const std::string& robot_id, int n,
                             uint64_t last_sequence) {
  const auto entries = static_cast<uint64_t>(n);
  if (entries > ctx.limits.max_correction_scans) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "corrections: " + std::to_string(n) + " entries exceed server.max_correction_scans = " +
                std::to_string(ctx.limits.max_correction_scans)};
  }
  const uint64_t in_log = ctx.map.retained_records_bound();
  // None retained (retention off, or no checkpoint yet): planning says why, at once.
  if (!ctx.map.retains_scans() || in_log == 0) return grpc::Status::OK;
  const uint64_t retained =
      std::min(in_log, last_sequence == UINT64_MAX ? last_sequence : last_sequence + 1);
  if (entries > retained) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "corrections: " + std::to_string(n) + " entries, but robot '" + robot_id +
                "' has at most " + std::to_string(retained) +
                " retained scans (storage.retention_mb, storage.retention_s)"};
  }
  return grpc::Status::OK;
}

// The entries as a CorrectionSpec's poses; the first bad one's status otherwise.
grpc::Status ReadPoses(const ServiceContext& ctx, const v1::CorrectPosesRequest& request,
                       CorrectionSpec* spec) {
  for (int i = 0; i < request.corrections_size(); ++i) {
    const v1::PoseCorrection& c = request.corrections(i);
    const std::string field = "corrections[" + std::to_string(i) + "]";
    if (!c.has_pose()) return {grpc::StatusCode::INVALID_ARGUMENT, field + ".pose: missing"};
    Pose pose;
    if (grpc::Status s = CheckPose(c.pose(), ctx.map.params(), ctx.limits, &pose); !s.ok()) {
      return {s.error_code(), field + "." + s.error_message()};
    }
    if (!spec->poses.emplace(c.sequence(), pose).second) {
      return {grpc::StatusCode::INVALID_ARGUMENT,
              field + ".sequence: " + std::to_string(c.sequence()) +
                  " is listed twice; each scan may be corrected once per request"};
    }
  }
  return grpc::Status::OK;
}

// CorrectPoses after its request's bytes were judged and parsed into call->request.
void CorrectParsed(ServiceContext& ctx, CorrectionCall* call, const std::string& peer,
                   PrincipalRef who) {
  const v1::CorrectPosesRequest& request = call->request;
  uint64_t last_sequence = 0;
  if (grpc::Status s = Admissible(ctx, *who, request.robot_id(), &last_sequence); !s.ok()) {
    return call->Answer(s);
  }
  const int n = request.corrections_size();
  if (n == 0) return call->Answer({grpc::StatusCode::INVALID_ARGUMENT, "corrections: empty"});
  if (grpc::Status s = CheckEntryCount(ctx, request.robot_id(), n, last_sequence); !s.ok()) {
    return call->Answer(s);
  }
  grpc::Status refusal;
  std::shared_ptr<Permit> permit = CorrectionPermit(*who, &refusal);
  if (!refusal.ok()) return call->Answer(refusal);
  CorrectionSpec spec;
  spec.robot_id = request.robot_id();
  if (grpc::Status s = ReadPoses(ctx, request, &spec); !s.ok()) return call->Answer(s);
  Submit(ctx, call, std::move(who), peer, std::move(permit), std::move(spec),
         call->response.mutable_summary(), "poses_corrected");
}

}  // namespace

grpc::ServerUnaryReactor* StartCorrectPoses(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                            PrincipalRef who, const grpc::ByteBuffer* request,
                                            grpc::ByteBuffer* response) {
  auto* reactor = new CorrectionCall(response);
  if (grpc::Status s = CheckRequestBytes(ctx, *request); !s.ok()) {
    reactor->Answer(s);
    return reactor;
  }
  grpc::ByteBuffer bytes(*request);  // shares the slices; Deserialize consumes its argument
  if (!grpc::SerializationTraits<v1::CorrectPosesRequest>::Deserialize(&bytes, &reactor->request)
           .ok()) {
    reactor->Answer({grpc::StatusCode::INVALID_ARGUMENT,
                     "request: not a valid bgkmap.v1.CorrectPosesRequest message"});
    return reactor;
  }
  CorrectParsed(ctx, reactor, call->peer(), std::move(who));
  return reactor;
}

grpc::ServerUnaryReactor* StartRemoveScans(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::RemoveScansRequest* request,
                                           v1::RemoveScansResponse* response) {
  auto* reactor = new CorrectionCall(nullptr);
  uint64_t last_sequence = 0;
  if (grpc::Status s = Admissible(ctx, *who, request->robot_id(), &last_sequence); !s.ok()) {
    reactor->Answer(s);
    return reactor;
  }
  if (request->first_sequence() > request->last_sequence()) {
    reactor->Answer({grpc::StatusCode::INVALID_ARGUMENT,
                     "first_sequence: " + std::to_string(request->first_sequence()) +
                         " is above last_sequence " + std::to_string(request->last_sequence())});
    return reactor;
  }
  grpc::Status refusal;
  std::shared_ptr<Permit> permit = CorrectionPermit(*who, &refusal);
  if (!refusal.ok()) {
    reactor->Answer(refusal);
    return reactor;
  }
  CorrectionSpec spec;
  spec.robot_id = request->robot_id();
  spec.remove = {request->first_sequence(), request->last_sequence()};
  Submit(ctx, reactor, std::move(who), call->peer(), std::move(permit), std::move(spec),
         response->mutable_summary(), "scans_removed");
  return reactor;
}

}  // namespace bgkmap
