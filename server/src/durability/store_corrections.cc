// StoreDurability's part of pose corrections: resolving a correction against the retained log,
// re-integrating it, and journaling it (docs/semantics.md, "Pose corrections").
#include <algorithm>
#include <functional>
#include <set>
#include <string>

#include "durability/store_durability.h"

namespace bgkmap {
namespace {

std::string Robot(const std::string& id) { return "robot '" + id + "'"; }

// A robot's retained scan records that a correction names, by sequence number, and the oldest
// and newest sequence numbers the retained log holds of the robot.
struct RetainedScans {
  std::map<uint64_t, storage::LogRecord> named;
  uint64_t oldest = UINT64_MAX;
  uint64_t newest = 0;
};

Result<RetainedScans> FindRetainedScans(const storage::TileStore& store, uint64_t from,
                                        const std::string& robot_id,
                                        const std::function<bool(uint64_t)>& named) {
  RetainedScans out;
  Status walked = store.log().ForEach(
      from,
      [&](uint64_t version, Result<storage::LogRecord> record) -> Status {
        if (!record.ok()) {
          return Status::DataLoss("the retained log is damaged at version " +
                                  std::to_string(version) + ": " + record.status().message());
        }
        if (record->type != storage::LogRecord::Type::kScan || record->robot_id != robot_id) {
          return Status::Ok();
        }
        out.oldest = std::min(out.oldest, record->sequence);
        out.newest = std::max(out.newest, record->sequence);
        if (named(record->sequence)) out.named.emplace(record->sequence, std::move(*record));
        return Status::Ok();
      },
      storage::ScanLog::LogRead::kHeaders);  // a named scan is prepared again from its raw scan
  if (!walked.ok()) return walked;
  return out;
}

// FailedPrecondition when the correction names scans no longer retained, InvalidArgument when
// it names scans never logged.
Status CheckRetained(const RetainedScans& found, const std::string& robot_id,
                     const std::map<uint64_t, Pose>& poses, const CorrectionRange& remove) {
  const std::string retained =
      found.oldest == UINT64_MAX
          ? "none of its scans is retained"
          : "its oldest retained scan is sequence " + std::to_string(found.oldest);
  if (remove) {
    if (remove->first < found.oldest) {
      return Status::FailedPrecondition("cannot remove " + Robot(robot_id) + "'s scans from " +
                                        std::to_string(remove->first) + ": " + retained +
                                        " (storage.retention_mb, storage.retention_s)");
    }
    if (found.named.empty()) {
      return Status::InvalidArgument(Robot(robot_id) + " has no scan with sequence in [" +
                                     std::to_string(remove->first) + ", " +
                                     std::to_string(remove->second) + "]");
    }
  }
  for (const auto& [sequence, pose] : poses) {
    if (found.named.contains(sequence)) continue;
    if (sequence < found.oldest) {
      return Status::FailedPrecondition("cannot correct sequence " + std::to_string(sequence) +
                                        " of " + Robot(robot_id) + ": " + retained +
                                        " (storage.retention_mb, storage.retention_s)");
    }
    return Status::InvalidArgument(
        "sequence " + std::to_string(sequence) + " of " + Robot(robot_id) +
        " was never ingested (or was removed); its last is " + std::to_string(found.newest));
  }
  return Status::Ok();
}

// Prepares `record` (sequence `sequence`) again from its raw scan with `pose` and adds it to
// `plan` as a replacement and a rewritten record.
Status Revise(const storage::TileStore& store, storage::LogRecord record, uint64_t sequence,
              const Pose& pose, CorrectionPlan* plan) {
  Result<std::optional<RawScan>> raw = store.log().LoadRawScan(record.version);
  if (!raw.ok()) return raw.status();
  if (!raw->has_value()) {
    return Status::FailedPrecondition(
        "sequence " + std::to_string(sequence) + " of " + Robot(plan->robot_id) +
        " was logged without its raw points (before storage.retention_mb was set): it cannot "
        "be corrected");
  }
  auto revised = std::make_shared<RawScan>(std::move(**raw));
  revised->pose = pose;
  Result<PreparedScan> prepared =
      PrepareScan(store.params(), revised->points, revised->pose, revised->frame_is_map);
  if (!prepared.ok()) {
    return Status::InvalidArgument("pose of sequence " + std::to_string(sequence) + ": " +
                                   prepared.status().message());
  }
  prepared->stamp_ns = record.stamp_ns;  // a corrected pose, the same map time
  auto scan = std::make_shared<const PreparedScan>(std::move(prepared).value());
  plan->replacements.emplace(record.version, scan);
  record.scan = scan;
  record.raw_scan = std::move(revised);
  plan->rewritten.push_back(std::move(record));
  return Status::Ok();
}

}  // namespace

bool StoreDurability::retains_scans() const { return store_->options().retention.enabled(); }

uint64_t StoreDurability::retained_records_bound() const {
  std::shared_lock lock(reopen_mu_);
  if (!retains_scans()) return 0;
  const std::vector<uint64_t> bases = store_->Bases();
  if (bases.empty()) return 0;
  const uint64_t last = store_->log().last_version();
  return last > bases.front() ? last - bases.front() : 0;
}

Result<CorrectionPlan> StoreDurability::PlanCorrection(const std::string& robot_id,
                                                       const std::map<uint64_t, Pose>& poses,
                                                       const CorrectionRange& remove) const {
  std::shared_lock lock(reopen_mu_);
  if (!retains_scans()) {
    return Status::FailedPrecondition(
        "this map keeps no scans to correct: storage.retention_mb is 0");
  }
  const std::vector<uint64_t> bases = store_->Bases();
  if (bases.empty()) {
    return Status::FailedPrecondition(
        "no scan is retained for corrections yet (the store was opened without retention "
        "until now; scans from the next checkpoint on can be corrected)");
  }
  Result<RetainedScans> found =
      FindRetainedScans(*store_, bases.front(), robot_id, [&](uint64_t sequence) {
        return remove ? sequence >= remove->first && sequence <= remove->second
                      : poses.contains(sequence);
      });
  if (!found.ok()) return found.status();
  if (Status s = CheckRetained(*found, robot_id, poses, remove); !s.ok()) return s;

  CorrectionPlan plan;
  plan.robot_id = robot_id;
  std::set<TileKey> seeds;
  for (auto& [sequence, record] : found->named) {
    const std::vector<TileKey> old = record.scan->ChangeableTiles();
    seeds.insert(old.begin(), old.end());
    if (remove) {
      plan.replacements.emplace(record.version, nullptr);
      plan.removed.push_back(record.version);
    } else if (Status s = Revise(*store_, std::move(record), sequence, poses.at(sequence), &plan);
               !s.ok()) {
      return s;
    }
  }
  plan.seed_tiles.assign(seeds.begin(), seeds.end());
  // The newest retained checkpoint below the first revised scan.
  const uint64_t first = plan.replacements.begin()->first;
  for (uint64_t b : bases) {
    if (b < first) plan.base = b;
  }
  return plan;
}

Result<storage::Reintegration> StoreDurability::Reintegrate(const CorrectionPlan& plan,
                                                            uint64_t end, bool plan_only) const {
  std::shared_lock lock(reopen_mu_);
  storage::ReintegrationRequest request;
  request.base = plan.base;
  request.end = end;
  request.seed_tiles = plan.seed_tiles;
  request.replacements = plan.replacements;
  request.plan_only = plan_only;
  Result<storage::Reintegration> out = storage::Reintegrate(*store_, request);
  if (!out.ok() && out.status().code() == Status::Code::kInvalidArgument) {
    // The base or a record went meanwhile (retention moved on): the caller may plan again.
    return Status::FailedPrecondition("the correction's history is no longer retained: " +
                                      out.status().message());
  }
  return out;
}

Status StoreDurability::RecordCorrection(const CorrectionPlan& plan, uint64_t version) {
  std::shared_lock lock(reopen_mu_);
  std::vector<uint64_t> revised;
  for (const auto& [v, scan] : plan.replacements) revised.push_back(v);
  const storage::LogRecord record = storage::LogRecord::Correction(
      version, plan.robot_id, plan.base, plan.seed_tiles, std::move(revised));
  Status s = store_->ApplyCorrection(record, plan.rewritten, plan.removed);
  if (!store_->log().write_failure().ok()) write_failed_.store(true);
  NotePause(s);
  return s;
}

}  // namespace bgkmap
