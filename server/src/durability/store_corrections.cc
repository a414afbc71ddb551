// StoreDurability's part of pose corrections: resolving a correction against the retained log,
// re-integrating it, and journaling it (docs/semantics.md, "Pose corrections").
#include <algorithm>
#include <set>
#include <string>

#include "durability/store_durability.h"

namespace bgkmap {
namespace {

std::string Robot(const std::string& id) { return "robot '" + id + "'"; }

}  // namespace

bool StoreDurability::retains_scans() const { return store_->options().retention.enabled(); }

Result<CorrectionPlan> StoreDurability::PlanCorrection(const CorrectionSpec& spec) const {
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
  auto wanted = [&](uint64_t sequence) {
    return spec.remove ? sequence >= spec.remove->first && sequence <= spec.remove->second
                       : spec.poses.contains(sequence);
  };
  std::map<uint64_t, storage::LogRecord> found;  // by sequence
  uint64_t oldest = UINT64_MAX, newest = 0;
  Status walked = store_->log().ForEach(
      bases.front(), [&](uint64_t version, Result<storage::LogRecord> record) -> Status {
        if (!record.ok()) {
          return Status::DataLoss("the retained log is damaged at version " +
                                  std::to_string(version) + ": " + record.status().message());
        }
        if (record->type != storage::LogRecord::Type::kScan || record->robot_id != spec.robot_id) {
          return Status::Ok();
        }
        oldest = std::min(oldest, record->sequence);
        newest = std::max(newest, record->sequence);
        if (wanted(record->sequence)) found.emplace(record->sequence, std::move(*record));
        return Status::Ok();
      });
  if (!walked.ok()) return walked;
  const std::string retained =
      oldest == UINT64_MAX ? "none of its scans is retained"
                           : "its oldest retained scan is sequence " + std::to_string(oldest);
  if (spec.remove) {
    if (spec.remove->first < oldest) {
      return Status::FailedPrecondition("cannot remove " + Robot(spec.robot_id) + "'s scans from " +
                                        std::to_string(spec.remove->first) + ": " + retained +
                                        " (storage.retention_mb, storage.retention_s)");
    }
    if (found.empty()) {
      return Status::InvalidArgument(Robot(spec.robot_id) + " has no scan with sequence in [" +
                                     std::to_string(spec.remove->first) + ", " +
                                     std::to_string(spec.remove->second) + "]");
    }
  }
  for (const auto& [sequence, pose] : spec.poses) {
    if (found.contains(sequence)) continue;
    if (sequence < oldest) {
      return Status::FailedPrecondition("cannot correct sequence " + std::to_string(sequence) +
                                        " of " + Robot(spec.robot_id) + ": " + retained +
                                        " (storage.retention_mb, storage.retention_s)");
    }
    return Status::InvalidArgument(
        "sequence " + std::to_string(sequence) + " of " + Robot(spec.robot_id) +
        " was never ingested (or was removed); its last is " + std::to_string(newest));
  }

  CorrectionPlan plan;
  plan.robot_id = spec.robot_id;
  std::set<TileKey> seeds;
  for (auto& [sequence, record] : found) {
    const std::vector<TileKey> old = record.scan->ChangeableTiles();
    seeds.insert(old.begin(), old.end());
    if (spec.remove) {
      plan.replacements.emplace(record.version, nullptr);
      plan.removed.push_back(record.version);
      continue;
    }
    Result<std::optional<storage::ScanSource>> source = store_->log().LoadSource(record.version);
    if (!source.ok()) return source.status();
    if (!source->has_value()) {
      return Status::FailedPrecondition(
          "sequence " + std::to_string(sequence) + " of " + Robot(spec.robot_id) +
          " was logged without its raw points (before storage.retention_mb was set): it cannot "
          "be corrected");
    }
    auto revised = std::make_shared<storage::ScanSource>(std::move(**source));
    revised->pose = spec.poses.at(sequence);
    Result<PreparedScan> prepared =
        PrepareScan(store_->params(), revised->points, revised->pose, revised->frame_is_map);
    if (!prepared.ok()) {
      return Status::InvalidArgument("pose of sequence " + std::to_string(sequence) + ": " +
                                     prepared.status().message());
    }
    prepared->stamp_ns = record.stamp_ns;  // a corrected pose, the same map time
    auto scan = std::make_shared<const PreparedScan>(std::move(prepared).value());
    plan.replacements.emplace(record.version, scan);
    record.scan = scan;
    record.source = std::move(revised);
    plan.rewritten.push_back(std::move(record));
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
