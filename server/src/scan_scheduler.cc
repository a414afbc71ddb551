#include "scan_scheduler.h"

#include <algorithm>
#include <boost/asio/post.hpp>

namespace bgkmap {

struct ScanScheduler::Job {
  uint64_t version = 0;                      // 0 for a barrier
  std::shared_ptr<const PreparedScan> scan;  // null for a clear or a barrier
  std::string robot_id;
  uint64_t sequence = 0;
  uint64_t previous_sequence = 0;  // the robot's before this scan: restored if it is refused
  Stamp stamp;
  CellBox clear_box;
  std::function<void(ScanOutcome)> on_applied;
  std::function<void(uint64_t, std::vector<TileKey>, Status)> on_cleared;
  std::function<void(uint64_t)> on_barrier;
  ExclusiveChange exclusive;  // with on_exclusive_done: an exclusive change
  std::function<void(uint64_t, Status)> on_exclusive_done;
  int pending = 0;  // unfinished changes this one waits for
  std::vector<Job*> dependents;
};

ScanScheduler::ScanScheduler(MapStore& store, boost::asio::thread_pool& pool, uint32_t max_robots,
                             TilesChanged on_tiles_changed)
    : store_(store),
      pool_(pool),
      max_robots_(max_robots),
      on_tiles_changed_(std::move(on_tiles_changed)) {}

ScanScheduler::~ScanScheduler() { WaitIdle(); }

bool ScanScheduler::IsDuplicate(const std::string& robot_id, uint64_t sequence) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  return it != robots_.end() && sequence <= it->second.last_sequence;
}

void ScanScheduler::CountRejected(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  if (auto it = robots_.find(robot_id); it != robots_.end()) ++it->second.scans_rejected;
}

void ScanScheduler::CountDuplicate(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  if (auto it = robots_.find(robot_id); it != robots_.end()) ++it->second.scans_duplicate;
}

ScanScheduler::Admission ScanScheduler::SubmitScan(const std::string& robot_id, uint64_t sequence,
                                                   Stamp stamp,
                                                   std::shared_ptr<const PreparedScan> scan,
                                                   std::function<void(ScanOutcome)> on_applied) {
  Job* ready = nullptr;
  {
    std::lock_guard lock(mu_);
    auto it = robots_.find(robot_id);
    if (it == robots_.end()) {
      if (robots_.size() >= max_robots_) return Admission::kTooManyRobots;
      it = robots_.emplace(robot_id, RobotProgress{}).first;
      it->second.robot_id = robot_id;
    } else if (sequence <= it->second.last_sequence) {
      ++it->second.scans_duplicate;
      return Admission::kDuplicate;
    }
    RobotProgress& robot = it->second;
    auto job = std::make_unique<Job>();
    job->robot_id = robot_id;
    job->sequence = sequence;
    job->previous_sequence = robot.last_sequence;
    job->stamp = stamp;
    robot.last_sequence = sequence;
    robot.last_stamp = stamp;
    ++robot.scans_applied;
    robot.points_kept += scan->counts.kept;

    job->scan = std::move(scan);
    job->on_applied = std::move(on_applied);
    Job* j = AdmitLocked(std::move(job));
    if (j->pending == 0) ready = j;
  }
  if (ready != nullptr) PostReady({ready});
  return Admission::kAdmitted;
}

void ScanScheduler::SubmitBarrier(std::function<void(uint64_t)> fn) {
  Job* ready = nullptr;
  {
    std::lock_guard lock(mu_);
    auto job = std::make_unique<Job>();
    job->on_barrier = std::move(fn);
    Job* j = AdmitLocked(std::move(job));
    if (j->pending == 0) ready = j;
  }
  if (ready != nullptr) PostReady({ready});
}

void ScanScheduler::SubmitExclusive(ExclusiveChange fn,
                                    std::function<void(uint64_t, Status)> on_done) {
  Job* ready = nullptr;
  {
    std::lock_guard lock(mu_);
    auto job = std::make_unique<Job>();
    job->exclusive = std::move(fn);
    job->on_exclusive_done = std::move(on_done);
    Job* j = AdmitLocked(std::move(job));  // no scan: ordered like a clear
    if (j->pending == 0) ready = j;
  }
  if (ready != nullptr) PostReady({ready});
}

void ScanScheduler::Restore(uint64_t version,
                            const std::map<std::string, uint64_t>& robot_sequences) {
  std::lock_guard lock(mu_);
  next_version_ = version + 1;
  applied_version_ = version;
  for (const auto& [id, sequence] : robot_sequences) {
    RobotProgress& r = robots_[id];
    r.robot_id = id;
    r.last_sequence = sequence;
  }
}

void ScanScheduler::SubmitClear(
    const CellBox& box, std::function<void(uint64_t, std::vector<TileKey>, Status)> on_cleared) {
  Job* ready = nullptr;
  {
    std::lock_guard lock(mu_);
    auto job = std::make_unique<Job>();
    job->clear_box = box;
    job->on_cleared = std::move(on_cleared);
    Job* j = AdmitLocked(std::move(job));
    if (j->pending == 0) ready = j;
  }
  if (ready != nullptr) PostReady({ready});
}

ScanScheduler::Job* ScanScheduler::AdmitLocked(std::unique_ptr<Job> owned) {
  Job* job = owned.get();
  const bool barrier = job->on_barrier != nullptr;
  if (!barrier) job->version = next_version_++;
  std::vector<Job*> deps;
  if (job->scan == nullptr) {
    // A barrier: after every change admitted so far.
    for (auto& [j, _] : active_) deps.push_back(j);
  } else {
    if (barrier_ != nullptr) deps.push_back(barrier_);
    for (TileKey k : job->scan->write_tiles) {
      TileOrder& o = order_[k];
      if (o.last_writer != nullptr) deps.push_back(o.last_writer);
      deps.insert(deps.end(), o.readers.begin(), o.readers.end());
      o.last_writer = job;
      o.readers.clear();
    }
    for (TileKey k : job->scan->read_tiles) {
      TileOrder& o = order_[k];
      if (o.last_writer != nullptr) deps.push_back(o.last_writer);
      o.readers.push_back(job);
    }
  }
  std::sort(deps.begin(), deps.end());
  deps.erase(std::unique(deps.begin(), deps.end()), deps.end());
  for (Job* d : deps) {
    if (d == job) continue;
    d->dependents.push_back(job);
    ++job->pending;
  }
  if (job->scan == nullptr) barrier_ = job;
  active_.emplace(job, std::move(owned));
  return job;
}

void ScanScheduler::PostReady(const std::vector<Job*>& ready) {
  for (Job* j : ready) {
    boost::asio::post(pool_, [this, j] { Run(j); });
  }
}

void ScanScheduler::Run(Job* job) {
  if (job->on_barrier) {
    // Everything admitted before has finished, so the applied version covers all of it.
    job->on_barrier(applied_version());
    Finish(job, false);
    return;
  }
  if (job->exclusive) {
    // Not journaled: the change makes itself durable (or undoes itself) inside `exclusive`.
    Result<std::vector<TileKey>> changed = job->exclusive(job->version);
    auto callback = std::move(job->on_exclusive_done);
    const uint64_t version = job->version;
    Finish(job, changed.ok());
    if (changed.ok() && on_tiles_changed_ && !changed->empty()) on_tiles_changed_(*changed);
    if (callback) callback(version, changed.status());
    return;
  }
  // The change's tiles are brought into memory before it is journaled: a store that cannot be
  // read refuses the change like a journal that cannot be written.
  Result<MapStore::Pins> pins = job->scan != nullptr ? store_.PinForScan(*job->scan)
                                                     : store_.PinForClear(job->clear_box);
  ChangeRecord change;
  Status journaled = pins.status();
  if (journal_ != nullptr && journaled.ok()) {
    change.version = job->version;
    change.scan = job->scan;
    change.robot_id = job->robot_id;
    change.sequence = job->sequence;
    change.stamp = job->stamp;
    change.clear_box = job->clear_box;
    journaled = journal_->Record(change);
  }
  // Watchers are told after Finish(), so the applied version they read covers this change.
  if (job->scan != nullptr) {
    ScanOutcome outcome;
    outcome.version = job->version;
    outcome.status = journaled;
    if (journaled.ok()) {
      outcome.report = store_.ApplyScan(*job->scan, job->version);
      if (journal_ != nullptr) journal_->Applied(job->scan->write_tiles);
    }
    auto callback = std::move(job->on_applied);
    Finish(job, journaled.ok());
    if (on_tiles_changed_ && !outcome.report.changed_tiles.empty()) {
      on_tiles_changed_(outcome.report.changed_tiles);
    }
    if (callback) callback(std::move(outcome));
  } else {
    std::vector<TileKey> changed;
    if (journaled.ok()) {
      changed = store_.ClearBox(job->clear_box, job->version);
      if (journal_ != nullptr) journal_->Applied(changed);
    }
    auto callback = std::move(job->on_cleared);
    const uint64_t version = job->version;
    Finish(job, journaled.ok());
    if (on_tiles_changed_ && !changed.empty()) on_tiles_changed_(changed);
    if (callback) callback(version, std::move(changed), journaled);
  }
}

void ScanScheduler::Finish(Job* job, bool applied_change) {
  std::vector<Job*> ready;
  uint64_t applied = 0;
  {
    std::lock_guard lock(mu_);
    for (Job* d : job->dependents) {
      if (--d->pending == 0) ready.push_back(d);
    }
    if (job->scan != nullptr && !applied_change) {
      // Refused by the journal: a retry of this sequence number must be accepted.
      if (auto it = robots_.find(job->robot_id); it != robots_.end()) {
        RobotProgress& r = it->second;
        --r.scans_applied;
        r.points_kept -= job->scan->counts.kept;
        if (r.last_sequence == job->sequence) r.last_sequence = job->previous_sequence;
      }
    }
    if (job->scan != nullptr) {
      if (applied_change) ++scans_applied_;
      // Forget the ordering entries that point at this job: nothing can wait on it any more.
      for (TileKey k : job->scan->write_tiles) {
        auto it = order_.find(k);
        if (it == order_.end()) continue;
        if (it->second.last_writer == job) it->second.last_writer = nullptr;
        if (it->second.last_writer == nullptr && it->second.readers.empty()) order_.erase(it);
      }
      for (TileKey k : job->scan->read_tiles) {
        auto it = order_.find(k);
        if (it == order_.end()) continue;
        auto& r = it->second.readers;
        r.erase(std::remove(r.begin(), r.end(), job), r.end());
        if (it->second.last_writer == nullptr && r.empty()) order_.erase(it);
      }
    }
    if (barrier_ == job) barrier_ = nullptr;
    // Advance the applied watermark over every contiguous finished version.
    if (job->version != 0) finished_ahead_.insert(job->version);
    while (!finished_ahead_.empty() && *finished_ahead_.begin() == applied_version_ + 1) {
      applied_version_ = *finished_ahead_.begin();
      finished_ahead_.erase(finished_ahead_.begin());
    }
    applied = applied_version_;
    active_.erase(job);  // destroys the job
    if (active_.empty()) idle_cv_.notify_all();
  }
  store_.SetMapVersion(applied);
  PostReady(ready);
}

uint64_t ScanScheduler::applied_version() const {
  std::lock_guard lock(mu_);
  return applied_version_;
}

uint64_t ScanScheduler::assigned_version() const {
  std::lock_guard lock(mu_);
  return next_version_ - 1;
}

uint64_t ScanScheduler::scans_applied() const {
  std::lock_guard lock(mu_);
  return scans_applied_;
}

std::optional<uint64_t> ScanScheduler::LastSequence(const std::string& robot_id) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  return it->second.last_sequence;
}

std::vector<RobotProgress> ScanScheduler::Robots() const {
  std::lock_guard lock(mu_);
  std::vector<RobotProgress> out;
  out.reserve(robots_.size());
  for (const auto& [_, r] : robots_) out.push_back(r);
  return out;
}

void ScanScheduler::WaitIdle() {
  std::unique_lock lock(mu_);
  idle_cv_.wait(lock, [this] { return active_.empty(); });
}

}  // namespace bgkmap
