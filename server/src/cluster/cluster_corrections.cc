// Pose corrections and scan removals on a shard (docs/scale-out.md, "Corrections are log
// entries"). The log holds every scan as sent, so it is the cluster's retained scans: a
// correction is resolved against it as a single server resolves one against its retained log,
// appended as one entry naming the revised scans by their log sequences, and each replica whose
// partition (with its halo) a revised scan meets, before or after the revision, rebuilds it when
// it reads the entry: the log's entries before it replayed with every revision in force, so the
// partition is what a single server's re-integration makes of it, bit for bit.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <set>

#include "bgkmap/storage/reintegration.h"
#include "cluster/cluster_node.h"

namespace bgkmap::cluster {
namespace {

std::string Robot(const std::string& id) { return "robot '" + id + "'"; }

// The scans a correction names that the log holds (admitted, not removed), by robot sequence;
// and the robot's oldest and newest of those.
struct Named {
  std::map<uint64_t, LoggedScan> scans;
  uint64_t oldest = UINT64_MAX;
  uint64_t newest = 0;
};

Named FindNamed(const LogIndex& index, const Revisions& in_force, const CorrectionSpec& spec) {
  Named out;
  for (const auto& [sequence, scan] : index.scans) {
    auto r = in_force.find(scan.log_sequence);
    if (r != in_force.end() && r->second.removed) continue;  // gone, as on a single server
    out.oldest = std::min(out.oldest, sequence);
    out.newest = std::max(out.newest, sequence);
    const bool named = spec.remove
                           ? sequence >= spec.remove->first && sequence <= spec.remove->second
                           : spec.poses.contains(sequence);
    if (named) out.scans.emplace(sequence, scan);
  }
  return out;
}

// The single server's refusals (store_corrections.cc, CheckRetained), with the cluster's
// reason a scan is not kept (a trimmed log).
Status CheckNamed(const Named& found, const CorrectionSpec& spec) {
  const std::string kept =
      found.oldest == UINT64_MAX
          ? "none of its scans is in the cluster's log"
          : "its oldest scan in the cluster's log is sequence " + std::to_string(found.oldest);
  if (spec.remove) {
    if (spec.remove->first < found.oldest) {
      return Status::FailedPrecondition("cannot remove " + Robot(spec.robot_id) + "'s scans from " +
                                        std::to_string(spec.remove->first) + ": " + kept +
                                        " (cluster.trim_lag_entries)");
    }
    if (found.scans.empty()) {
      return Status::InvalidArgument(Robot(spec.robot_id) + " has no scan with sequence in [" +
                                     std::to_string(spec.remove->first) + ", " +
                                     std::to_string(spec.remove->second) + "]");
    }
  }
  for (const auto& [sequence, pose] : spec.poses) {
    if (found.scans.contains(sequence)) continue;
    if (sequence < found.oldest) {
      return Status::FailedPrecondition("cannot correct sequence " + std::to_string(sequence) +
                                        " of " + Robot(spec.robot_id) + ": " + kept +
                                        " (cluster.trim_lag_entries)");
    }
    return Status::InvalidArgument(
        "sequence " + std::to_string(sequence) + " of " + Robot(spec.robot_id) +
        " was never ingested (or was removed); its last is " + std::to_string(found.newest));
  }
  return Status::Ok();
}

// Corrections need every entry from the log's start (a partition is rebuilt from it).
Status WholeLogKept(const NatsClient& nats, uint32_t trim_lag_entries) {
  if (trim_lag_entries > 0) {
    return Status::FailedPrecondition(
        "pose corrections and scan removals on a cluster replay the log from its start, and "
        "cluster.trim_lag_entries = " +
        std::to_string(trim_lag_entries) + " trims it: set it to 0 to keep every entry");
  }
  Result<uint64_t> first = FirstSequence(nats);
  if (!first.ok()) return Status::IoError(first.status().message());
  if (*first > 1) {
    return Status::FailedPrecondition(
        "the cluster's log was trimmed to entry " + std::to_string(*first) +
        ": the scans before it cannot be replayed (cluster.trim_lag_entries: 0 keeps every "
        "entry)");
  }
  return Status::Ok();
}

}  // namespace

Result<PreparedScan> ClusterNode::PrepareLogged(uint64_t log_sequence, const Pose* pose) const {
  Result<NatsPtr<natsMsg>> msg = GetEntry(*nats_, *trust_, log_sequence);
  if (!msg.ok()) return Status::IoError(msg.status().message());
  Result<std::string> payload = EntryPayload(*nats_, msg->get());
  if (!payload.ok()) return Status::IoError(payload.status().message());
  v1::Scan scan;
  if (!scan.ParseFromString(*payload)) {
    return Status::DataLoss("log entry " + std::to_string(log_sequence) + " does not decode");
  }
  PreparedScan prepared;
  if (Status s = prepare_(scan, pose, &prepared); !s.ok()) return s;
  return prepared;
}

// A correction resolved against the log's entries up to `last`.
struct ClusterNode::Resolved {
  explicit Resolved(LogIndex log) : index(std::move(log)) {}
  LogIndex index;
  uint64_t last = 0;
  Revisions own;  // the entry's own revisions
  Revisions all;  // in force once it is applied: earlier corrections' and its own
  std::set<PartitionKey> touched;
  CellBox changes;
  storage::AffectedTiles affected;
};

Result<std::unique_ptr<ClusterNode::Resolved>> ClusterNode::Resolve(const CorrectionSpec& spec) {
  if (Status s = WholeLogKept(*nats_, config_.trim_lag_entries); !s.ok()) return s;
  Result<uint64_t> last = LastSequence(*nats_);
  if (!last.ok()) return Status::IoError(last.status().message());
  Result<LogIndex> index = IndexLog(*nats_, *trust_, rule_, spec.robot_id, *last);
  if (!index.ok()) return Status::IoError(index.status().message());
  Result<Revisions> in_force = ReadRevisions(*nats_, *trust_, index->corrections);
  if (!in_force.ok()) return Status::IoError(in_force.status().message());
  const Named found = FindNamed(*index, *in_force, spec);
  if (Status s = CheckNamed(found, spec); !s.ok()) return s;
  if (spec.is_cancelled()) {
    return Status::FailedPrecondition("cancelled by its client before it was applied");
  }
  auto out = std::make_unique<Resolved>(std::move(*index));
  out->last = *last;
  out->all = *in_force;
  // The partitions whose halos the scans meet as first sent, as revised so far, and as revised
  // now: all of them are rebuilt.
  auto reaching = [&](const PreparedScan& prepared) {
    const CellBox reach = layout_.Reach(prepared);
    out->changes.Extend(reach.min);
    out->changes.Extend(reach.max);
    for (PartitionKey p : layout_.Covering(reach)) out->touched.insert(p);
  };
  for (const auto& [sequence, scan] : found.scans) {
    out->touched.insert(scan.touched.begin(), scan.touched.end());
    if (!scan.changes.empty()) {
      out->changes.Extend(scan.changes.min);
      out->changes.Extend(scan.changes.max);
    }
    // The scan as the log holds it now (as sent, or as revised so far): the single server's
    // seed of the affected tiles.
    auto r = in_force->find(scan.log_sequence);
    Result<PreparedScan> current =
        PrepareLogged(scan.log_sequence, r != in_force->end() ? &r->second.pose : nullptr);
    if (!current.ok()) return current.status();
    if (r != in_force->end()) reaching(*current);
    out->affected.Seed(current->ChangeableTiles());
    if (spec.remove) {
      out->own[scan.log_sequence] = Revision{true, {}};
      continue;
    }
    const Pose& pose = spec.poses.at(sequence);
    Result<PreparedScan> revised = PrepareLogged(scan.log_sequence, &pose);
    if (!revised.ok()) {
      if (revised.status().code() != Status::Code::kInvalidArgument) return revised.status();
      return Status::InvalidArgument("pose of sequence " + std::to_string(sequence) + ": " +
                                     revised.status().message());
    }
    reaching(*revised);
    out->own[scan.log_sequence] = Revision{false, pose};
  }
  for (const auto& [entry, revision] : out->own) out->all.insert_or_assign(entry, revision);
  return out;
}

Status ClusterNode::GrowAffected(uint64_t first, uint64_t last, const Admitted& admitted,
                                 Resolved* resolved, const std::string& own_payload,
                                 Interleaved* seen) const {
  if (first > last) return Status::Ok();
  Status unreadable = Status::Ok();  // a region copy out of reach: the replicas would wait
  Status read =
      ReadLogRange(*nats_, first, last, /*headers_only=*/false, [&](uint64_t entry, natsMsg* msg) {
        // The entries the replicas integrate, judged as they judge them (Dispatch).
        if (!unreadable.ok() || !VerifyEntry(*trust_, msg, /*headers_only=*/false).ok()) return;
        Result<LogEntryHeader> h = ReadEntryHeader(msg);
        if (!h.ok()) return;
        if (h->kind == LogEntryHeader::Kind::kCorrect && seen != nullptr) {
          const std::string_view payload(natsMsg_GetData(msg),
                                         static_cast<size_t>(natsMsg_GetDataLength(msg)));
          if (payload == own_payload && seen->own == 0) {
            seen->own = entry;
          } else {
            seen->other = true;
          }
        }
        if (!admitted(entry, *h)) return;
        auto r = resolved->all.find(entry);
        if (r != resolved->all.end() && r->second.removed) return;  // no record any more
        Result<std::string> payload = EntryPayload(*nats_, msg);
        if (!payload.ok() && payload.status().code() == Status::Code::kUnavailable) {
          unreadable = payload.status();
          return;
        }
        v1::Scan scan;
        PreparedScan prepared;
        if (!payload.ok() || !scan.ParseFromString(*payload) ||
            !prepare_(scan, r != resolved->all.end() ? &r->second.pose : nullptr, &prepared).ok()) {
          return;  // skipped by every replica too
        }
        resolved->affected.Add(prepared, resolved->own.contains(entry));
      });
  if (!unreadable.ok()) return unreadable;
  if (!read.ok()) return Status::IoError(read.message());
  return Status::Ok();
}

Result<CorrectionOutcome> ClusterNode::Correct(const CorrectionSpec& spec) {
  const auto start = std::chrono::steady_clock::now();
  // Resolved again from the start when another correction is appended meanwhile.
  for (int attempt = 0; attempt < kCorrectionAttempts; ++attempt) {
    Result<std::unique_ptr<Resolved>> resolved = Resolve(spec);
    if (!resolved.ok()) return resolved.status();
    Resolved& r = **resolved;
    // The single server's affected tiles: its re-integration's, from the first revised scan on.
    const std::vector<uint64_t>& admitted = r.index.admitted;
    Status grown = GrowAffected(
        r.own.begin()->first, r.last,
        [&](uint64_t entry, const LogEntryHeader&) {
          return std::binary_search(admitted.begin(), admitted.end(), entry);
        },
        &r, "", nullptr);
    if (!grown.ok()) return grown;
    // Partitions a revised scan now reaches get owners before the entry is read.
    for (PartitionKey p : r.touched) {
      if (Status s = members_->AddPartition(p); !s.ok()) return Status::IoError(s.message());
    }
    for (Interleaved seen; !seen.other;) {
      const std::string payload = EncodeCorrection(r.own, r.affected.tiles());
      Result<std::optional<uint64_t>> at =
          AppendCorrection(*nats_, *trust_, spec.robot_id, payload,
                           {r.touched.begin(), r.touched.end()}, r.changes, r.last);
      if (!at.ok()) return Status::IoError(at.status().message());
      std::optional<uint64_t> stored = *at;
      if (!stored) {
        // Entries were appended since: the affected tiles grow over them, in the log's order.
        Result<uint64_t> last = LastSequence(*nats_);
        if (!last.ok()) return Status::IoError(last.status().message());
        grown = GrowAffected(
            r.last + 1, *last,
            [&](uint64_t, const LogEntryHeader& h) { return r.index.judge.Admits(h); }, &r, payload,
            &seen);
        if (!grown.ok()) return grown;
        spdlog::info("event=correction_log_grew from={} to={}", r.last, *last);
        r.last = *last;
        if (seen.own != 0) stored = seen.own;  // in the log already: applied as it is
      }
      if (stored) {
        CorrectionOutcome outcome;
        outcome.version = *stored;
        outcome.scans_revised = r.own.size();
        outcome.records_in_history = *stored - 1;  // every partition it touches replays them all
        outcome.records_replayed = *stored - 1;
        outcome.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        return outcome;
      }
    }
  }
  return Status::Unavailable(
      "other corrections kept being appended while this one was resolved; "
      "send it again");
}

void ClusterNode::ApplyCorrection(uint64_t sequence, const LogEntryHeader& header,
                                  const std::vector<TileKey>& affected,
                                  const std::vector<std::shared_ptr<PartitionReplica>>& to) {
  std::vector<std::shared_ptr<PartitionReplica>> rebuilt;
  for (const auto& r : to) {
    if (std::binary_search(header.touched.begin(), header.touched.end(), r->key())) {
      rebuilt.push_back(r);
    } else {
      // Its cells do not change, but a single server stamps the affected tiles it holds.
      r->ApplyStamp(sequence, affected);
    }
  }
  if (rebuilt.empty()) return;
  if (Status s = RebuildAt(sequence, rebuilt, affected); !s.ok()) {
    // The partitions keep their tiles without the correction: said loudly, since they now
    // differ from a single server's map (a trimmed log, or a log that cannot be read).
    spdlog::error("event=correction_not_applied sequence={} partitions={} reason=\"{}\"", sequence,
                  rebuilt.size(), s.message());
    for (const auto& r : rebuilt) r->ApplyStamp(sequence, affected);
  }
}

Status ClusterNode::RebuildAt(uint64_t sequence,
                              const std::vector<std::shared_ptr<PartitionReplica>>& replicas,
                              const std::vector<TileKey>& affected) {
  const auto start = std::chrono::steady_clock::now();
  // The revisions in force at the entry: its own and every earlier correction's.
  Result<LogIndex> index = IndexLog(*nats_, *trust_, rule_, "", sequence);
  if (!index.ok()) return index.status();
  Result<Revisions> revisions = ReadRevisions(*nats_, *trust_, index->corrections);
  if (!revisions.ok()) return revisions.status();
  // Fresh copies that never serve, fed the log's entries before it with the revisions.
  std::vector<std::shared_ptr<PartitionReplica>> copies;
  for (const auto& r : replicas) {
    Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
    if (!map.ok()) return map.status();
    copies.push_back(std::make_shared<PartitionReplica>(*nats_, *trust_, layout_, r->key(),
                                                        std::move(map).value(), UINT64_MAX, rule_));
  }
  if (sequence > 1) {
    Status read = ReadLogRange(
        *nats_, 1, sequence - 1, /*headers_only=*/false,
        [&](uint64_t entry, natsMsg* msg) { Dispatch(entry, msg, copies, &*revisions); });
    if (!read.ok()) return read;
  }
  for (size_t i = 0; i < replicas.size(); ++i) {
    replicas[i]->AdoptRebuilt(*copies[i], sequence, affected);
  }
  spdlog::info(
      "event=partitions_rebuilt sequence={} partitions={} revisions={} entries_replayed={} "
      "seconds={:.3f}",
      sequence, replicas.size(), revisions->size(), sequence - 1,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return Status::Ok();
}

}  // namespace bgkmap::cluster
