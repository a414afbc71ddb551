// The robots of the whole cluster, as the log says: a headers-only reader of the log from its
// start (no scan payload crosses the network) that judges every scan entry by the single server's
// rule with its limits (serving/robot_sequence.h: duplicates, server.max_sequence_jump,
// server.max_robots) and forgets a robot at its retirement entry, in the log's order. Every
// partition replica judges the same entries by the same rule in the same order, so the ledger's
// verdict on an entry is the verdict every partition reached: a shard that appended a scan (or a
// retirement) waits for the ledger to read that entry and answers with its verdict, as a single
// server answers at admission.
//
// On a trimmed log the ledger starts from a partition checkpoint's robot table (every replica
// keeps every robot's last sequence) and reads the entries after it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/server/robot_stats.h"
#include "cluster/cluster_log.h"
#include "cluster/cluster_trust.h"
#include "cluster/membership.h"
#include "cluster/nats_client.h"
#include "cluster/partition_checkpoint.h"
#include "serving/correction_stats.h"
#include "serving/robot_sequence.h"

namespace bgkmap::cluster {

// What the log's order made of one entry.
struct LedgerVerdict {
  // A scan: its admission by the rule (kAdmitted also for an entry that is not a scan).
  RobotAdmission admission = RobotAdmission::kAdmitted;
  uint64_t previous = 0;  // a scan: its robot's last sequence before it (0: not known)
  // A retirement: the robot as it was, or nullopt if it was not known (nothing retired).
  std::optional<RobotStats> retired;
  // The robot's retirements before this entry: a retired robot starts its sequence again, so its
  // scans' message ids (the log's de-duplication) name the epoch (AppendScan).
  uint64_t epoch = 0;
};

class RobotLedger {
 public:
  // Starts reading at once; `nats`, `trust` and `members` outlive it.
  RobotLedger(const NatsClient& nats, const ClusterTrust& trust, const Membership& members,
              RobotSequenceRule rule);
  ~RobotLedger();  // stops and joins the reader
  RobotLedger(const RobotLedger&) = delete;
  RobotLedger& operator=(const RobotLedger&) = delete;

  // The verdict on entry `sequence`, once the ledger has read it: Unavailable after `timeout_ms`;
  // nullopt if it was read so long ago that its verdict is no longer kept (kKeptVerdicts).
  Result<std::optional<LedgerVerdict>> WaitVerdict(uint64_t sequence, int64_t timeout_ms) const;
  // Blocks until the ledger has read entry `sequence` (false after `timeout_ms`).
  bool WaitRead(uint64_t sequence, int64_t timeout_ms) const;
  // How many times `robot_id` was retired, as of the last entry read (0 on a log trimmed below
  // a retirement: the checkpoints keep no retirements).
  uint64_t Epoch(const std::string& robot_id) const;
  std::vector<RobotStats> Robots() const;  // sorted by id, as of the last entry read
  uint64_t last_sequence() const;          // the last entry read (0: none)
  // How many of the entries up to `sequence` (read already) changed the map: admitted scans,
  // clears, imports and corrections (a single server gives a correction a version too); refused
  // scans, retirements, exports and entries that fail their HMAC change nothing. What a single
  // server fed the same changes calls the version of the map after them (ExportMap writes it;
  // counted from the ledger's start).
  uint64_t ChangesAt(uint64_t sequence) const;
  // ChangesAt for the entries up to `sequence` (read already), as a copy that outlives the
  // ledger: an export's archive is streamed after the call that made it (a node may be leaving).
  std::function<uint64_t(uint64_t)> ChangesUpTo(uint64_t sequence) const;
  // Scans admitted since the ledger started (its log's start or checkpoint): the cluster's
  // scans applied, as a single server counts them since its start.
  uint64_t scans_admitted() const;
  // The cluster's corrections as the log holds them (since the ledger's start, as a single
  // server counts them since its start): correction entries (applied), the scans they name
  // (scans_revised), the entries before each that its rebuilds replay (records_replayed) and
  // the refusals shards recorded (failed, kRefusedSubject). No in_progress or last_seconds: a
  // shard's own.
  CorrectionStats corrections() const;

  static constexpr size_t kKeptVerdicts = 65536;

 private:
  void Run();
  // Where to start: the log's first entry, or after a checkpoint's robot table when trimmed.
  uint64_t Seed();
  void Read(uint64_t sequence, natsMsg* msg);
  // The scans correction entry `sequence` names (0, with a warning, if it cannot be read).
  uint64_t CorrectionScans(uint64_t sequence) const;

  const NatsClient& nats_;
  const ClusterTrust& trust_;
  const Membership& members_;
  const RobotSequenceRule rule_;
  std::atomic<bool> stop_{false};

  mutable std::mutex mu_;
  mutable std::condition_variable read_cv_;
  uint64_t last_ = 0;
  uint64_t scans_admitted_ = 0;
  CorrectionStats corrections_;
  std::vector<uint64_t> unchanged_;  // the entries that changed nothing, ascending
  uint64_t first_ = 1;               // the first entry the ledger reads
  std::map<std::string, RobotStats> robots_;
  std::map<std::string, uint64_t> retirements_;
  std::map<uint64_t, LedgerVerdict> verdicts_;  // the newest kKeptVerdicts entries' verdicts
  std::thread reader_;
};

}  // namespace bgkmap::cluster
