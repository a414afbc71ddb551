#include "rpc/handlers/ingest_pipeline.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <memory>

#include "bgkmap/server/log_safe.h"
#include "rpc/access_control.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

// The scan's sensor position and heading (the yaw of its x axis) on the map's ground plane; the
// pose was checked (unit quaternion) by PrepareScanMessage.
RobotPose SensorPose(const v1::Scan& scan) {
  const v1::Quaternion& q = scan.pose().rotation();
  const double yaw =
      std::atan2(2 * (q.w() * q.z() + q.x() * q.y()), 1 - 2 * (q.y() * q.y() + q.z() * q.z()));
  return {scan.sequence(), scan.pose().translation().x(), scan.pose().translation().y(), yaw};
}

// The robot and sequence number every ack repeats.
v1::ScanAck BaseAck(const v1::Scan& scan) {
  v1::ScanAck ack;
  ack.set_robot_id(scan.robot_id());
  ack.set_sequence(scan.sequence());
  return ack;
}

v1::ScanAck Rejected(ServiceContext& ctx, v1::ScanAck ack, const grpc::Status& status) {
  spdlog::warn("event=scan_rejected robot=\"{}\" sequence={} code={} reason=\"{}\"",
               LogSafe(ack.robot_id(), 128), ack.sequence(), static_cast<int>(status.error_code()),
               LogSafe(status.error_message()));
  ack.set_status(v1::ACK_REJECTED);
  ack.set_code(status.error_code());
  ack.set_message(status.error_message());
  ack.set_map_version(ctx.map.known_version());
  return ack;
}

// Code 0, but the message tells the robot where it stands: a robot whose scans all come back
// as duplicates learns the number to continue after (or that someone else used its id).
v1::ScanAck DuplicateAck(ServiceContext& ctx, const v1::Scan& scan, uint64_t last_sequence) {
  v1::ScanAck ack = BaseAck(scan);
  ack.set_status(v1::ACK_DUPLICATE);
  ack.set_message("duplicate: sequence " + std::to_string(scan.sequence()) +
                  " is not above the robot's last admitted sequence " +
                  std::to_string(last_sequence) + "; not applied again");
  ack.set_map_version(ctx.map.known_version());
  return ack;
}

grpc::Status SequenceJump(const ServiceContext& ctx, const v1::Scan& scan, uint64_t last) {
  return {grpc::StatusCode::OUT_OF_RANGE,
          "sequence: " + std::to_string(scan.sequence()) +
              " is more than server.max_sequence_jump = " +
              std::to_string(ctx.limits.max_sequence_jump) + " above the robot's last sequence " +
              std::to_string(last) + " (a robot's sequence numbers increase by small steps)"};
}

// What the robot hears of an admitted scan once the map is done with it: applied; a duplicate
// (a retry the map's log had stored already); or not applied. A scan the map could not make
// durable may be sent again (UNAVAILABLE); one the map refused keeps the map's code.
void Answer(ServiceContext& ctx, v1::ScanAck ack, const ScanPointCounts& counts,
            const ScanOutcome& outcome, const AckCallback& done) {
  const Status::Code code = outcome.status.code();
  if (code == Status::Code::kIoError || code == Status::Code::kDataLoss) {
    grpc::Status s(grpc::StatusCode::UNAVAILABLE,
                   "scan not applied: cannot persist it: " + outcome.status.message());
    spdlog::error("event=scan_not_persisted robot=\"{}\" sequence={} reason=\"{}\"",
                  LogSafe(ack.robot_id(), 128), ack.sequence(), LogSafe(outcome.status.message()));
    ack.set_status(v1::ACK_REJECTED);
    ack.set_code(s.error_code());
    ack.set_message(s.error_message());
    ack.set_map_version(outcome.version);
    done(std::move(ack), s);
    return;
  }
  if (!outcome.status.ok()) {
    const grpc::Status s = ToGrpcStatus(outcome.status);
    done(Rejected(ctx, std::move(ack), s), s);
    return;
  }
  if (outcome.already_logged) {
    ack.set_status(v1::ACK_DUPLICATE);
    ack.set_message("duplicate: robot '" + ack.robot_id() + "' sequence " +
                    std::to_string(ack.sequence()) +
                    " is already in the cluster's log; not applied again");
  } else {
    ack.set_status(v1::ACK_APPLIED);
    ToProto(counts, ack.mutable_counts());
    for (TileKey k : outcome.changed_tiles) ToProto(k, ack.add_changed_tiles());
  }
  ack.set_map_version(outcome.version);
  done(std::move(ack), grpc::Status::OK);
}

// What the robot hears of a scan the map did not admit by its sequence number.
void NotAdmitted(ServiceContext& ctx, const v1::Scan& scan, RobotAdmission admission,
                 uint64_t last_sequence, const AckCallback& done) {
  switch (admission) {
    case RobotAdmission::kAdmitted:
      return;
    case RobotAdmission::kDuplicate:
      done(DuplicateAck(ctx, scan, last_sequence), grpc::Status::OK);
      return;
    case RobotAdmission::kSequenceJump: {
      const grpc::Status s = SequenceJump(ctx, scan, last_sequence);
      done(RejectedAck(ctx, scan, s), s);
      return;
    }
    case RobotAdmission::kTooManyRobots: {
      grpc::Status s(grpc::StatusCode::RESOURCE_EXHAUSTED,
                     "robot_id: '" + scan.robot_id() + "' would exceed server.max_robots = " +
                         std::to_string(ctx.limits.max_robots));
      done(RejectedAck(ctx, scan, s), s);
      return;
    }
  }
}

}  // namespace

v1::ScanAck RejectedAck(ServiceContext& ctx, const v1::Scan& scan, const grpc::Status& status) {
  return Rejected(ctx, BaseAck(scan), status);
}

void IngestScanMessage(ServiceContext& ctx, const Principal& who, const v1::Scan& scan,
                       AckCallback done) {
  const auto received = std::chrono::steady_clock::now();
  if (grpc::Status s = CheckRobotId(scan.robot_id()); !s.ok()) {
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  // Before the duplicate check: another robot's id learns nothing of that robot's sequence.
  if (!who.MayIngestAs(scan.robot_id())) {
    const grpc::Status s = NotThisRobot(who, scan.robot_id());
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  // Retries after a lost ack are common: answer them before paying for preparation.
  if (uint64_t last = 0; ctx.map.TakeDuplicate(scan.robot_id(), scan.sequence(), &last)) {
    done(DuplicateAck(ctx, scan, last), grpc::Status::OK);
    return;
  }
  auto prepared = std::make_shared<PreparedScan>();
  std::shared_ptr<RawScan> raw;
  const bool keep_raw = ctx.map.retains_scans() || ctx.latest_scans != nullptr;
  if (grpc::Status s = PrepareScanMessage(scan, ctx.map.params(), ctx.limits, prepared.get(),
                                          keep_raw ? &raw : nullptr);
      !s.ok()) {
    ctx.map.CountRejected(scan.robot_id());
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  const Stamp stamp{scan.stamp().seconds(), scan.stamp().nanos()};
  // The live views see a scan once it is applied (not a duplicate, not refused).
  std::shared_ptr<const RawScan> latest = ctx.latest_scans != nullptr ? raw : nullptr;
  ScanOrigin origin{scan.robot_id(),
                    scan.sequence(),
                    stamp,
                    ctx.map.retains_scans() ? std::move(raw) : nullptr,
                    [&scan] { return scan.SerializeAsString(); },
                    SensorPose(scan)};
  uint64_t last_sequence = 0;
  const RobotAdmission admission = ctx.map.SubmitScan(
      std::move(origin), prepared,
      [&ctx, ack = BaseAck(scan), counts = prepared->counts, done, latest, stamp,
       received](ScanOutcome outcome) {
        if (outcome.status.ok() && !outcome.already_logged) {
          ctx.latencies.of(RequestPhase::kScan).Record(std::chrono::steady_clock::now() - received);
          if (latest != nullptr) {
            ctx.latest_scans->Record(ack.robot_id(), ack.sequence(), stamp, latest->pose,
                                     latest->points);
          }
        }
        Answer(ctx, ack, counts, outcome, done);
      },
      &last_sequence);
  NotAdmitted(ctx, scan, admission, last_sequence, done);
}

}  // namespace bgkmap
