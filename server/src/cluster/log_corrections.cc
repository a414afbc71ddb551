#include "cluster/log_corrections.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "bgkmap/v1/cluster.pb.h"

namespace bgkmap::cluster {

std::string EncodeCorrection(const Revisions& revisions, const std::set<TileKey>& affected) {
  v1::LogCorrection out;
  for (TileKey k : affected) {
    v1::TileKey* key = out.add_affected();
    key->set_x(k.x);
    key->set_y(k.y);
  }
  for (const auto& [sequence, r] : revisions) {
    if (r.removed) {
      out.add_removed(sequence);
      continue;
    }
    v1::LogCorrection::Revised* revised = out.add_revised();
    revised->set_log_sequence(sequence);
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) revised->add_pose(r.pose.rotation(row, col));
    }
    for (int i = 0; i < 3; ++i) revised->add_pose(r.pose.translation(i));
  }
  return out.SerializeAsString();
}

std::vector<TileKey> CorrectionAffected(std::string_view payload) {
  v1::LogCorrection in;
  std::vector<TileKey> out;
  if (!in.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) return out;
  out.reserve(static_cast<size_t>(in.affected_size()));
  for (const v1::TileKey& k : in.affected()) out.push_back({k.x(), k.y()});
  std::sort(out.begin(), out.end());
  return out;
}

bool LogJudge::Admits(const LogEntryHeader& h) {
  if (h.kind == LogEntryHeader::Kind::kRetire) robots_.erase(h.robot_id);
  if (h.kind != LogEntryHeader::Kind::kScan) return false;
  auto it = robots_.find(h.robot_id);
  const std::optional<uint64_t> previous =
      it == robots_.end() ? std::nullopt : std::optional<uint64_t>(it->second);
  if (rule_.Judge(previous, h.robot_sequence, robots_.size()) != RobotAdmission::kAdmitted) {
    return false;
  }
  robots_[h.robot_id] = h.robot_sequence;
  return true;
}

Status MergeCorrection(const std::string& payload, Revisions* into) {
  v1::LogCorrection in;
  if (!in.ParseFromString(payload)) return Status::DataLoss("the correction does not decode");
  for (const v1::LogCorrection::Revised& revised : in.revised()) {
    if (revised.pose_size() != 12) return Status::DataLoss("a corrected pose has not 12 values");
  }
  for (uint64_t sequence : in.removed()) into->insert_or_assign(sequence, Revision{true, {}});
  for (const v1::LogCorrection::Revised& revised : in.revised()) {
    Revision r;
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) r.pose.rotation(row, col) = revised.pose(row * 3 + col);
    }
    for (int i = 0; i < 3; ++i) r.pose.translation(i) = revised.pose(9 + i);
    auto it = into->find(revised.log_sequence());
    if (it != into->end() && it->second.removed) continue;  // removed stays removed
    into->insert_or_assign(revised.log_sequence(), r);
  }
  return Status::Ok();
}

Result<LogIndex> IndexLog(const NatsClient& nats, const ClusterTrust& trust, RobotSequenceRule rule,
                          const std::string& robot_id, uint64_t last) {
  LogIndex index(rule);
  Status read =
      ReadLogRange(nats, 1, last, /*headers_only=*/true, [&](uint64_t entry, natsMsg* msg) {
        if (!VerifyEntry(trust, msg, /*headers_only=*/true).ok()) return;
        Result<LogEntryHeader> h = ReadEntryHeader(msg);
        if (!h.ok()) return;
        if (h->kind == LogEntryHeader::Kind::kCorrect) index.corrections.push_back(entry);
        if (!index.judge.Admits(*h)) return;
        index.admitted.push_back(entry);
        if (h->robot_id == robot_id) {
          index.scans.emplace(h->robot_sequence,
                              LoggedScan{h->robot_sequence, entry, h->touched, h->changes});
        }
      });
  if (!read.ok()) return read;
  return index;
}

Result<Revisions> ReadRevisions(const NatsClient& nats, const ClusterTrust& trust,
                                const std::vector<uint64_t>& entries) {
  Revisions out;
  for (uint64_t entry : entries) {
    Result<NatsPtr<natsMsg>> msg = GetEntry(nats, trust, entry);
    if (!msg.ok() && msg.status().code() == Status::Code::kFailedPrecondition) {
      spdlog::warn("event=log_correction_passed sequence={} reason=\"{}\"", entry,
                   msg.status().message());
      continue;
    }
    if (!msg.ok()) return msg.status();
    const std::string payload(natsMsg_GetData(msg->get()),
                              static_cast<size_t>(natsMsg_GetDataLength(msg->get())));
    if (Status s = MergeCorrection(payload, &out); !s.ok()) {
      spdlog::error("event=log_correction_passed sequence={} reason=\"{}\"", entry, s.message());
    }
  }
  return out;
}

}  // namespace bgkmap::cluster
