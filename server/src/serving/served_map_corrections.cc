// ServedMap's pose corrections: planned against the log, run as one change over the tiles the
// re-integration reads and writes, and switched in at once (docs/semantics.md, "Pose
// corrections").
#include <algorithm>
#include <chrono>

#include "serving/served_map.h"

namespace bgkmap {

struct ServedMap::CorrectionJob {
  CorrectionPlan plan;
  std::shared_ptr<const std::atomic<bool>> cancelled;  // CorrectionSpec::cancelled
  std::function<void(CorrectionOutcome)> done;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  int attempts = 0;
};

namespace {
// A correction whose region keeps growing (a robot streaming on at its edge) runs, after this
// many attempts, as an exclusive change: after everything before it, before everything after.
constexpr int kRegionAttempts = 3;

Status CancelledByClient() {
  return Status::FailedPrecondition("cancelled by its client before it was applied");
}
}  // namespace

CorrectionStats ServedMap::corrections() const {
  std::lock_guard lock(corrections_mu_);
  return corrections_;
}

void ServedMap::SubmitCorrection(CorrectionSpec spec, std::function<void(CorrectionOutcome)> done) {
  auto refuse = [&](const Status& s) {
    {
      std::lock_guard lock(corrections_mu_);
      ++corrections_.failed;
    }
    CorrectionOutcome outcome;
    outcome.status = s;
    done(std::move(outcome));
  };
  if (spec.is_cancelled()) return refuse(CancelledByClient());
  Result<CorrectionPlan> plan = durability_.PlanCorrection(spec.robot_id, spec.poses, spec.remove);
  if (!plan.ok()) return refuse(plan.status());
  if (spec.is_cancelled()) return refuse(CancelledByClient());
  // The region as the log holds it now; computed again, complete, when the correction runs.
  Result<storage::Reintegration> region =
      durability_.Reintegrate(*plan, UINT64_MAX, /*plan_only=*/true);
  if (!region.ok()) return refuse(region.status());
  auto job = std::make_shared<CorrectionJob>();
  job->plan = std::move(*plan);
  job->done = std::move(done);
  job->cancelled = std::move(spec.cancelled);
  {
    std::lock_guard lock(corrections_mu_);
    ++corrections_.in_progress;
  }
  ScheduleCorrection(std::move(job), std::move(region->needed));
}

void ServedMap::ScheduleCorrection(std::shared_ptr<CorrectionJob> job,
                                   std::vector<TileKey> region) {
  ++job->attempts;
  ChangeScheduler::Kind kind = ChangeScheduler::ExclusiveChange{};
  if (job->attempts <= kRegionAttempts) kind = ChangeScheduler::TileChange{region, {}};
  scheduler_.Submit(std::move(kind),
                    [this, job, region = std::move(region)](uint64_t version) mutable {
                      return RunCorrection(std::move(job), region, version);
                    });
}

ChangeScheduler::Done ServedMap::RunCorrection(std::shared_ptr<CorrectionJob> job,
                                               const std::vector<TileKey>& region,
                                               uint64_t version) {
  CorrectionOutcome outcome;
  outcome.version = version;
  auto finish = [&](std::vector<TileKey> changed) -> ChangeScheduler::Done {
    outcome.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - job->start).count();
    {
      std::lock_guard lock(corrections_mu_);
      --corrections_.in_progress;
      if (outcome.status.ok()) {
        ++corrections_.applied;
        corrections_.scans_revised += outcome.scans_revised;
        corrections_.records_replayed += outcome.records_replayed;
        corrections_.last_seconds = outcome.seconds;
      } else {
        ++corrections_.failed;
      }
    }
    return {std::move(changed), [job, outcome = std::move(outcome)] { job->done(outcome); }};
  };
  // Cancelled while it waited for its turn (or for its region to be pinned): dropped, so a
  // client that gave up never sees its correction applied later.
  if (job->cancelled != nullptr && job->cancelled->load()) {
    outcome.status = CancelledByClient();
    return finish({});
  }
  // Every record below `version` that touches the region is in the log now.
  Result<storage::Reintegration> rebuilt =
      durability_.Reintegrate(job->plan, version, /*plan_only=*/false);
  if (!rebuilt.ok()) {
    outcome.status = rebuilt.status();
    return finish({});
  }
  const bool exclusive = job->attempts > kRegionAttempts;
  if (!exclusive && !std::includes(region.begin(), region.end(), rebuilt->needed.begin(),
                                   rebuilt->needed.end())) {
    // Scans logged since the plan reach further: again, over the larger region, at a later
    // version (this one changes nothing).
    std::vector<TileKey> larger;
    std::set_union(region.begin(), region.end(), rebuilt->needed.begin(), rebuilt->needed.end(),
                   std::back_inserter(larger));
    return {{}, [this, job, larger = std::move(larger)]() mutable {
              ScheduleCorrection(std::move(job), std::move(larger));
            }};
  }
  Result<TileResidency::Pins> pins = residency_.Pin(rebuilt->affected, /*strict=*/true);
  if (!pins.ok()) {
    outcome.status = pins.status();
    return finish({});
  }
  // The last moment it can be dropped: once recorded it is the map's.
  if (job->cancelled != nullptr && job->cancelled->load()) {
    outcome.status = CancelledByClient();
    return finish({});
  }
  if (Status s = durability_.RecordCorrection(job->plan, version); !s.ok()) {
    outcome.status = Status::IoError("cannot persist it: " + s.message());
    return finish({});
  }
  // One switch under the tiles' locks: readers see the map before or after, never a mix.
  for (std::unique_ptr<Tile>& tile : rebuilt->tiles) {
    if (tile ==
        nullptr) {  // (kept until a checkpoint deletes its stored copy, like a cleared tile)
      tile = std::make_unique<Tile>(params().tile_size, KeepsPlaneMoments(params().method));
    }
    tile->set_version(version);
  }
  table_.ReplaceTiles(rebuilt->affected, rebuilt->tiles);
  summary_.MarkStale(rebuilt->affected);
  checkpointer_.MarkChanged(rebuilt->affected);
  residency_.SignalIfOverLimit();
  outcome.scans_revised = job->plan.replacements.size();
  outcome.records_replayed = rebuilt->records_replayed;
  outcome.records_in_history = rebuilt->records_in_history;
  outcome.changed_tiles = rebuilt->affected;
  return finish(std::move(rebuilt->affected));
}

}  // namespace bgkmap
