#include "rpc/handlers/ingest_pipeline.h"

#include <spdlog/spdlog.h>

#include <memory>

#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

v1::ScanAck BaseAck(const v1::Scan& scan) {
  v1::ScanAck ack;
  ack.set_robot_id(scan.robot_id());
  ack.set_sequence(scan.sequence());
  return ack;
}

v1::ScanAck DuplicateAck(ServiceContext& ctx, const v1::Scan& scan) {
  v1::ScanAck ack = BaseAck(scan);
  ack.set_status(v1::ACK_DUPLICATE);
  ack.set_map_version(ctx.map.applied_version());
  return ack;
}

}  // namespace

v1::ScanAck RejectedAck(ServiceContext& ctx, const v1::Scan& scan, const grpc::Status& status) {
  spdlog::warn("event=scan_rejected robot={} sequence={} code={} reason=\"{}\"",
               scan.robot_id().substr(0, 128), scan.sequence(),
               static_cast<int>(status.error_code()), status.error_message());
  v1::ScanAck ack = BaseAck(scan);
  ack.set_status(v1::ACK_REJECTED);
  ack.set_code(status.error_code());
  ack.set_message(status.error_message());
  ack.set_map_version(ctx.map.applied_version());
  return ack;
}

void IngestScanMessage(ServiceContext& ctx, const v1::Scan& scan, AckCallback done) {
  if (grpc::Status s = CheckRobotId(scan.robot_id()); !s.ok()) {
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  // Retries after a lost ack are common: answer them before paying for preparation.
  if (ctx.map.robots().IsDuplicate(scan.robot_id(), scan.sequence())) {
    ctx.map.robots().CountDuplicate(scan.robot_id());
    done(DuplicateAck(ctx, scan), grpc::Status::OK);
    return;
  }
  auto prepared = std::make_shared<PreparedScan>();
  if (grpc::Status s = PrepareScanMessage(scan, ctx.map.params(), ctx.limits, prepared.get());
      !s.ok()) {
    ctx.map.robots().CountRejected(scan.robot_id());
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  const Stamp stamp{scan.stamp().seconds(), scan.stamp().nanos()};
  v1::ScanAck applied = BaseAck(scan);
  const ServedMap::Admission admission = ctx.map.SubmitScan(
      {scan.robot_id(), scan.sequence(), stamp}, prepared,
      [applied, done, counts = prepared->counts](ScanOutcome outcome) mutable {
        if (!outcome.status.ok()) {
          // Not in the log, so not in the map: the robot may send it again.
          grpc::Status s(grpc::StatusCode::UNAVAILABLE,
                         "scan not applied: cannot persist it: " + outcome.status.message());
          spdlog::error("event=scan_not_persisted robot={} sequence={} reason=\"{}\"",
                        applied.robot_id().substr(0, 128), applied.sequence(),
                        outcome.status.message());
          applied.set_status(v1::ACK_REJECTED);
          applied.set_code(s.error_code());
          applied.set_message(s.error_message());
          applied.set_map_version(outcome.version);
          done(std::move(applied), s);
          return;
        }
        applied.set_status(v1::ACK_APPLIED);
        applied.set_map_version(outcome.version);
        ToProto(counts, applied.mutable_counts());
        for (TileKey k : outcome.report.changed_tiles) ToProto(k, applied.add_changed_tiles());
        done(std::move(applied), grpc::Status::OK);
      });
  switch (admission) {
    case ServedMap::Admission::kAdmitted:
      return;
    case ServedMap::Admission::kDuplicate:
      done(DuplicateAck(ctx, scan), grpc::Status::OK);
      return;
    case ServedMap::Admission::kTooManyRobots: {
      grpc::Status s(grpc::StatusCode::RESOURCE_EXHAUSTED,
                     "robot_id: '" + scan.robot_id() + "' would exceed server.max_robots = " +
                         std::to_string(ctx.limits.max_robots));
      done(RejectedAck(ctx, scan, s), s);
      return;
    }
  }
}

}  // namespace bgkmap
