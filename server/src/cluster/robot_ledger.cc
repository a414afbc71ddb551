#include "cluster/robot_ledger.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "bgkmap/v1/cluster.pb.h"

namespace bgkmap::cluster {

RobotLedger::RobotLedger(const NatsClient& nats, const ClusterTrust& trust,
                         const Membership& members, RobotSequenceRule rule)
    : nats_(nats), trust_(trust), members_(members), rule_(rule) {
  reader_ = std::thread([this] { Run(); });
}

RobotLedger::~RobotLedger() {
  stop_ = true;
  reader_.join();
}

uint64_t RobotLedger::Seed() {
  for (;;) {
    if (stop_) return 1;
    Result<uint64_t> first = FirstSequence(nats_);
    if (first.ok() && *first <= 1) return 1;
    Result<std::vector<PartitionKey>> partitions =
        first.ok() ? members_.ListRecordedPartitions() : first.status();
    if (partitions.ok()) {
      // Every replica keeps every robot's last sequence: any checkpoint the log still continues.
      for (PartitionKey p : *partitions) {
        Result<std::optional<PartitionCheckpoint>> c = ReadCheckpointRobots(nats_, trust_, p);
        if (!c.ok() || !c->has_value() || (*c)->log_sequence + 1 < *first) continue;
        std::lock_guard lock(mu_);
        for (const auto& [robot, sequence] : (*c)->robot_sequences) {
          robots_[robot].robot_id = robot;
          robots_[robot].last_sequence = sequence;
        }
        last_ = (*c)->log_sequence;
        first_ = last_ + 1;
        spdlog::info("event=robot_ledger_seeded log_sequence={} partition={} robots={}", last_,
                     PartitionName(p), robots_.size());
        return last_ + 1;
      }
    }
    spdlog::warn("event=robot_ledger_waiting reason=\"{}\"",
                 partitions.ok() ? "the log is trimmed and no checkpoint continues it"
                                 : partitions.status().message());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

void RobotLedger::Run() {
  const uint64_t start = Seed();
  FollowLogHeaders(nats_, start, stop_, "robot_ledger_open_failed",
                   [this](uint64_t entry, natsMsg* msg) { Read(entry, msg); });
}

void RobotLedger::Read(uint64_t sequence, natsMsg* msg) {
  LedgerVerdict verdict;
  // As the replicas do: an entry that fails its HMAC or its headers changes no robot.
  // (Refusals are counted once, by the node's log reader.)
  Result<LogEntryHeader> header = VerifyEntry(trust_, msg, /*headers_only=*/true).ok()
                                      ? ReadEntryHeader(msg)
                                      : Result<LogEntryHeader>(Status::FailedPrecondition(""));
  // A correction's count of scans is in its payload (this reader reads headers only).
  const uint64_t scans_revised =
      header.ok() && header->kind == LogEntryHeader::Kind::kCorrect ? CorrectionScans(sequence) : 0;
  std::lock_guard lock(mu_);
  if (header.ok() && header->kind == LogEntryHeader::Kind::kCorrect) {
    ++corrections_.applied;
    corrections_.scans_revised += scans_revised;
    corrections_.records_replayed += sequence - 1;  // every partition it rebuilds replays them
  } else if (header.ok() && header->kind == LogEntryHeader::Kind::kRefused) {
    ++corrections_.failed;
  }
  if (header.ok() && !header->robot_id.empty()) {
    auto epoch = retirements_.find(header->robot_id);
    verdict.epoch = epoch == retirements_.end() ? 0 : epoch->second;
  }
  if (header.ok() && header->kind == LogEntryHeader::Kind::kScan) {
    auto it = robots_.find(header->robot_id);
    const std::optional<uint64_t> last =
        it == robots_.end() ? std::nullopt : std::optional<uint64_t>(it->second.last_sequence);
    verdict.previous = last.value_or(0);
    verdict.admission = rule_.Judge(last, header->robot_sequence, robots_.size());
    if (verdict.admission == RobotAdmission::kAdmitted) {
      RobotStats& robot = robots_[header->robot_id];
      robot.robot_id = header->robot_id;
      robot.last_sequence = header->robot_sequence;
      ++robot.scans_applied;
      ++scans_admitted_;
    } else if (it != robots_.end()) {
      ++(verdict.admission == RobotAdmission::kDuplicate ? it->second.scans_duplicate
                                                         : it->second.scans_rejected);
    }
  } else if (header.ok() && header->kind == LogEntryHeader::Kind::kRetire) {
    auto it = robots_.find(header->robot_id);
    if (it != robots_.end()) {
      verdict.retired = std::move(it->second);
      robots_.erase(it);
      ++retirements_[header->robot_id];
    }
  }
  const bool changed = header.ok() && ((header->kind == LogEntryHeader::Kind::kScan &&
                                        verdict.admission == RobotAdmission::kAdmitted) ||
                                       header->kind == LogEntryHeader::Kind::kClear ||
                                       header->kind == LogEntryHeader::Kind::kImport ||
                                       header->kind == LogEntryHeader::Kind::kCorrect);
  if (!changed) unchanged_.push_back(sequence);
  verdicts_.emplace(sequence, std::move(verdict));
  while (verdicts_.size() > kKeptVerdicts) verdicts_.erase(verdicts_.begin());
  last_ = sequence;
  read_cv_.notify_all();
}

uint64_t RobotLedger::CorrectionScans(uint64_t sequence) const {
  Result<NatsPtr<natsMsg>> msg = GetEntry(nats_, trust_, sequence);
  v1::LogCorrection correction;
  if (msg.ok() &&
      correction.ParseFromArray(natsMsg_GetData(msg->get()), natsMsg_GetDataLength(msg->get()))) {
    return static_cast<uint64_t>(correction.revised_size() + correction.removed_size());
  }
  spdlog::warn("event=robot_ledger_correction_unread sequence={} reason=\"{}\"", sequence,
               msg.ok() ? "it does not decode" : msg.status().message());
  return 0;
}

CorrectionStats RobotLedger::corrections() const {
  std::lock_guard lock(mu_);
  return corrections_;
}

Result<std::optional<LedgerVerdict>> RobotLedger::WaitVerdict(uint64_t sequence,
                                                              int64_t timeout_ms) const {
  if (!WaitRead(sequence, timeout_ms)) {
    std::lock_guard lock(mu_);
    return Status::Unavailable("the cluster's robot ledger has read the log up to entry " +
                               std::to_string(last_) + ", not yet " + std::to_string(sequence));
  }
  std::lock_guard lock(mu_);
  auto it = verdicts_.find(sequence);
  if (it == verdicts_.end()) return std::optional<LedgerVerdict>();
  return std::optional<LedgerVerdict>(it->second);
}

bool RobotLedger::WaitRead(uint64_t sequence, int64_t timeout_ms) const {
  std::unique_lock lock(mu_);
  return read_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                           [&] { return last_ >= sequence; });
}

uint64_t RobotLedger::Epoch(const std::string& robot_id) const {
  std::lock_guard lock(mu_);
  auto it = retirements_.find(robot_id);
  return it == retirements_.end() ? 0 : it->second;
}

std::vector<RobotStats> RobotLedger::Robots() const {
  std::lock_guard lock(mu_);
  std::vector<RobotStats> out;
  out.reserve(robots_.size());
  for (const auto& [id, robot] : robots_) out.push_back(robot);
  return out;
}

uint64_t RobotLedger::ChangesAt(uint64_t sequence) const {
  std::lock_guard lock(mu_);
  if (sequence < first_) return 0;
  const auto unchanged = std::upper_bound(unchanged_.begin(), unchanged_.end(), sequence);
  return sequence - first_ + 1 - static_cast<uint64_t>(unchanged - unchanged_.begin());
}

std::function<uint64_t(uint64_t)> RobotLedger::ChangesUpTo(uint64_t sequence) const {
  std::lock_guard lock(mu_);
  std::vector<uint64_t> unchanged(unchanged_.begin(),
                                  std::upper_bound(unchanged_.begin(), unchanged_.end(), sequence));
  return [first = first_, unchanged = std::move(unchanged)](uint64_t s) -> uint64_t {
    if (s < first) return 0;
    const auto before = std::upper_bound(unchanged.begin(), unchanged.end(), s);
    return s - first + 1 - static_cast<uint64_t>(before - unchanged.begin());
  };
}

uint64_t RobotLedger::scans_admitted() const {
  std::lock_guard lock(mu_);
  return scans_admitted_;
}

uint64_t RobotLedger::last_sequence() const {
  std::lock_guard lock(mu_);
  return last_;
}

}  // namespace bgkmap::cluster
