// Pose corrections and scan removals in the cluster's log (docs/scale-out.md, "Corrections are
// log entries"): what the correction entries say, read back in the log's order, and the robot's
// admitted scans a new correction names.
//
// A correction entry names scans by their log sequences. The revisions in force at entry S are
// those of every correction entry up to S, in the log's order: a later pose replaces an earlier
// one, and a removed scan stays removed (a single server deletes its record, so nothing can
// name it again). A replica rebuilds its partition at S by replaying the log's entries before S
// with these revisions, as a single server's correction replays its retained log.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "cluster/cluster_log.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "serving/robot_sequence.h"

namespace bgkmap::cluster {

struct Revision {
  bool removed = false;
  Pose pose;  // the corrected pose (not removed)
};
// By the revised scan's log sequence.
using Revisions = std::map<uint64_t, Revision>;

// A v1::LogCorrection of `revisions` (bit for bit: poses as doubles).
std::string EncodeCorrection(const Revisions& revisions);
// Merges correction entry `payload` into `into` (a removal is kept over a later pose).
// DataLoss if it does not decode.
Status MergeCorrection(const std::string& payload, Revisions* into);

// One admitted scan of a robot, as the log's headers tell it.
struct LoggedScan {
  uint64_t robot_sequence = 0;
  uint64_t log_sequence = 0;
  std::vector<PartitionKey> touched;  // as first appended
  CellBox changes;
};

// What a headers-only pass over the log's entries 1..last finds.
struct LogIndex {
  std::vector<uint64_t> corrections;  // the correction entries' sequences, ascending
  // `robot_id`'s admitted scans (judged as every replica judges them: RobotSequenceRule,
  // retirements), by robot sequence; the first one of a sequence number (after a retirement the
  // robot's numbers start again).
  std::map<uint64_t, LoggedScan> scans;
};

// The headers-only pass (entries that fail their HMAC are passed, as the replicas pass them).
// FailedPrecondition if the log was trimmed; Unavailable if it cannot be read.
Result<LogIndex> IndexLog(const NatsClient& nats, const ClusterTrust& trust, RobotSequenceRule rule,
                          const std::string& robot_id, uint64_t last);

// The revisions in force after the correction entries `entries` (ascending), read by sequence.
// An entry that does not verify is passed (as the replicas pass it).
Result<Revisions> ReadRevisions(const NatsClient& nats, const ClusterTrust& trust,
                                const std::vector<uint64_t>& entries);

}  // namespace bgkmap::cluster
