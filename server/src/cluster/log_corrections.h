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
#include <set>
#include <string>
#include <string_view>
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

// A v1::LogCorrection of `revisions` (bit for bit: poses as doubles) and the tiles it affects
// (`affected`, sorted: storage::AffectedTiles).
std::string EncodeCorrection(const Revisions& revisions, const std::set<TileKey>& affected);
// The tiles correction entry `payload` affects, sorted (none if it does not decode).
std::vector<TileKey> CorrectionAffected(std::string_view payload);
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

// The robot-sequence rule over the log's entries in order, as every replica and the ledger
// apply it (serving/robot_sequence.h): scans judged, retirements forgetting their robot.
class LogJudge {
 public:
  explicit LogJudge(RobotSequenceRule rule) : rule_(rule) {}
  // The next entry's verified header: whether it is a scan the rule admits.
  bool Admits(const LogEntryHeader& header);

 private:
  RobotSequenceRule rule_;
  std::map<std::string, uint64_t> robots_;  // last admitted sequence, as the replicas keep it
};

// What a headers-only pass over the log's entries 1..last finds.
struct LogIndex {
  explicit LogIndex(RobotSequenceRule rule) : judge(rule) {}
  std::vector<uint64_t> corrections;  // the correction entries' sequences, ascending
  // `robot_id`'s admitted scans (judged as every replica judges them: RobotSequenceRule,
  // retirements), by robot sequence; the first one of a sequence number (after a retirement the
  // robot's numbers start again).
  std::map<uint64_t, LoggedScan> scans;
  std::vector<uint64_t> admitted;  // every robot's admitted scan entries, ascending
  LogJudge judge;                  // as of entry `last`: judges the entries after it
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
