#include "rpc/handlers/ingest_pipeline.h"

#include <spdlog/spdlog.h>

#include <memory>

#include "cluster/cluster_node.h"
#include "log_safe.h"
#include "rpc/access_control.h"
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

// Code 0, but the message tells the robot where it stands: a robot whose scans all come back
// as duplicates learns the number to continue after (or that someone else used its id).
v1::ScanAck DuplicateAck(ServiceContext& ctx, const v1::Scan& scan, uint64_t last_sequence) {
  v1::ScanAck ack = BaseAck(scan);
  ack.set_status(v1::ACK_DUPLICATE);
  ack.set_message("duplicate: sequence " + std::to_string(scan.sequence()) +
                  " is not above the robot's last admitted sequence " +
                  std::to_string(last_sequence) + "; not applied again");
  ack.set_map_version(ctx.map.applied_version());
  return ack;
}

grpc::Status SequenceJump(const ServiceContext& ctx, const v1::Scan& scan, uint64_t last) {
  return {grpc::StatusCode::OUT_OF_RANGE,
          "sequence: " + std::to_string(scan.sequence()) +
              " is more than server.max_sequence_jump = " +
              std::to_string(ctx.limits.max_sequence_jump) + " above the robot's last sequence " +
              std::to_string(last) + " (a robot's sequence numbers increase by small steps)"};
}

// A cluster node: the scan goes to the cluster's log, and the ack says it is there (durable on
// a majority of the log's replicas). The map version is its log sequence number.
void AppendToCluster(ServiceContext& ctx, const v1::Scan& scan, const PreparedScan& prepared,
                     const AckCallback& done) {
  Result<cluster::Appended> appended = ctx.cluster->Append(scan, prepared);
  if (!appended.ok()) {
    const grpc::Status s = ToGrpcStatus(appended.status());
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  v1::ScanAck ack = BaseAck(scan);
  if (appended->duplicate) {
    ack.set_status(v1::ACK_DUPLICATE);
    ack.set_message("duplicate: robot '" + scan.robot_id() + "' sequence " +
                    std::to_string(scan.sequence()) +
                    " is already in the cluster's log; not applied again");
  } else {
    ack.set_status(v1::ACK_APPLIED);
    ToProto(prepared.counts, ack.mutable_counts());
  }
  ack.set_map_version(appended->sequence);
  done(std::move(ack), grpc::Status::OK);
}

}  // namespace

v1::ScanAck RejectedAck(ServiceContext& ctx, const v1::Scan& scan, const grpc::Status& status) {
  spdlog::warn("event=scan_rejected robot=\"{}\" sequence={} code={} reason=\"{}\"",
               LogSafe(scan.robot_id(), 128), scan.sequence(),
               static_cast<int>(status.error_code()), LogSafe(status.error_message()));
  v1::ScanAck ack = BaseAck(scan);
  ack.set_status(v1::ACK_REJECTED);
  ack.set_code(status.error_code());
  ack.set_message(status.error_message());
  ack.set_map_version(ctx.map.applied_version());
  return ack;
}

void IngestScanMessage(ServiceContext& ctx, const Principal& who, const v1::Scan& scan,
                       AckCallback done) {
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
  if (uint64_t last = 0; ctx.cluster == nullptr &&
                         ctx.map.robots().IsDuplicate(scan.robot_id(), scan.sequence(), &last)) {
    ctx.map.robots().CountDuplicate(scan.robot_id());
    done(DuplicateAck(ctx, scan, last), grpc::Status::OK);
    return;
  }
  auto prepared = std::make_shared<PreparedScan>();
  std::shared_ptr<storage::ScanSource> source;
  if (grpc::Status s = PrepareScanMessage(scan, ctx.map.params(), ctx.limits, prepared.get(),
                                          ctx.map.retains_scans() ? &source : nullptr);
      !s.ok()) {
    ctx.map.robots().CountRejected(scan.robot_id());
    done(RejectedAck(ctx, scan, s), s);
    return;
  }
  if (ctx.cluster != nullptr) {
    AppendToCluster(ctx, scan, *prepared, done);
    return;
  }
  const Stamp stamp{scan.stamp().seconds(), scan.stamp().nanos()};
  v1::ScanAck applied = BaseAck(scan);
  uint64_t last_sequence = 0;
  const ServedMap::Admission admission = ctx.map.SubmitScan(
      {scan.robot_id(), scan.sequence(), stamp, std::move(source)}, prepared,
      [applied, done, counts = prepared->counts](ScanOutcome outcome) mutable {
        if (!outcome.status.ok()) {
          // Not in the log, so not in the map: the robot may send it again.
          grpc::Status s(grpc::StatusCode::UNAVAILABLE,
                         "scan not applied: cannot persist it: " + outcome.status.message());
          spdlog::error("event=scan_not_persisted robot=\"{}\" sequence={} reason=\"{}\"",
                        LogSafe(applied.robot_id(), 128), applied.sequence(),
                        LogSafe(outcome.status.message()));
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
      },
      &last_sequence);
  switch (admission) {
    case ServedMap::Admission::kAdmitted:
      return;
    case ServedMap::Admission::kDuplicate:
      done(DuplicateAck(ctx, scan, last_sequence), grpc::Status::OK);
      return;
    case ServedMap::Admission::kSequenceJump: {
      const grpc::Status s = SequenceJump(ctx, scan, last_sequence);
      done(RejectedAck(ctx, scan, s), s);
      return;
    }
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
