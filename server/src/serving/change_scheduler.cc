#include "serving/change_scheduler.h"

#include <algorithm>
#include <boost/asio/post.hpp>

namespace bgkmap {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};

}  // namespace

ChangeScheduler::ChangeScheduler(boost::asio::thread_pool& pool, TilesChanged on_tiles_changed,
                                 TilesApplied on_tiles_applied)
    : pool_(pool),
      on_tiles_changed_(std::move(on_tiles_changed)),
      on_tiles_applied_(std::move(on_tiles_applied)) {}

ChangeScheduler::~ChangeScheduler() { WaitIdle(); }

void ChangeScheduler::Restore(uint64_t version) {
  std::lock_guard lock(mu_);
  next_version_ = version + 1;
  applied_version_ = version;
}

uint64_t ChangeScheduler::Submit(Kind kind, Work work) {
  Job* ready = nullptr;
  uint64_t version = 0;
  {
    std::lock_guard lock(mu_);
    auto owned = std::make_unique<Job>();
    Job* job = owned.get();
    job->kind = std::move(kind);
    job->work = std::move(work);
    if (!std::holds_alternative<Barrier>(job->kind)) job->version = next_version_++;
    version = job->version;
    for (Job* d : DependenciesLocked(job)) {
      d->dependents.push_back(job);
      ++job->pending;
    }
    active_.emplace(job, std::move(owned));
    if (job->pending == 0) ready = job;
  }
  if (ready != nullptr) Post({ready});
  return version;
}

std::vector<ChangeScheduler::Job*> ChangeScheduler::DependenciesLocked(Job* job) {
  std::vector<Job*> deps;
  std::visit(Overloaded{
                 [&](const TileChange& change) {
                   if (exclusive_ != nullptr) deps.push_back(exclusive_);
                   for (TileKey k : change.write_tiles) {
                     TileOrder& o = order_[k];
                     if (o.last_writer != nullptr) deps.push_back(o.last_writer);
                     deps.insert(deps.end(), o.readers.begin(), o.readers.end());
                     o.last_writer = job;
                     o.readers.clear();
                   }
                   for (TileKey k : change.read_tiles) {
                     TileOrder& o = order_[k];
                     if (o.last_writer != nullptr) deps.push_back(o.last_writer);
                     o.readers.push_back(job);
                   }
                 },
                 [&](const auto&) {  // exclusive change or barrier: after everything so far
                   for (auto& [j, _] : active_) deps.push_back(j);
                   exclusive_ = job;
                 },
             },
             job->kind);
  std::sort(deps.begin(), deps.end());
  deps.erase(std::unique(deps.begin(), deps.end()), deps.end());
  std::erase(deps, job);  // a scan that reads a tile it writes
  return deps;
}

void ChangeScheduler::Post(const std::vector<Job*>& ready) {
  for (Job* j : ready) {
    boost::asio::post(pool_, [this, j] { Run(j); });
  }
}

void ChangeScheduler::Run(Job* job) {
  // A barrier runs once everything admitted before has finished: the applied version covers it.
  const uint64_t version =
      std::holds_alternative<Barrier>(job->kind) ? applied_version() : job->version;
  Done done = job->work(version);
  if (on_tiles_applied_ && !done.changed_tiles.empty()) {
    on_tiles_applied_(version, done.changed_tiles, done.changed_blocks);
  }
  Finish(job);  // destroys the job
  if (on_tiles_changed_ && !done.changed_tiles.empty()) on_tiles_changed_(done.changed_tiles);
  if (done.then) done.then();
}

void ChangeScheduler::ForgetLocked(Job* job) {
  // Forget the ordering entries that point at this job: nothing can wait on it any more.
  const auto* change = std::get_if<TileChange>(&job->kind);
  if (change == nullptr) {
    if (exclusive_ == job) exclusive_ = nullptr;
    return;
  }
  for (TileKey k : change->write_tiles) {
    auto it = order_.find(k);
    if (it == order_.end()) continue;
    if (it->second.last_writer == job) it->second.last_writer = nullptr;
    if (it->second.last_writer == nullptr && it->second.readers.empty()) order_.erase(it);
  }
  for (TileKey k : change->read_tiles) {
    auto it = order_.find(k);
    if (it == order_.end()) continue;
    std::erase(it->second.readers, job);
    if (it->second.last_writer == nullptr && it->second.readers.empty()) order_.erase(it);
  }
}

void ChangeScheduler::Finish(Job* job) {
  std::vector<Job*> ready;
  {
    std::lock_guard lock(mu_);
    for (Job* d : job->dependents) {
      if (--d->pending == 0) ready.push_back(d);
    }
    ForgetLocked(job);
    // Advance the applied watermark over every contiguous finished version.
    if (job->version != 0) finished_ahead_.insert(job->version);
    while (!finished_ahead_.empty() && *finished_ahead_.begin() == applied_version_ + 1) {
      applied_version_ = *finished_ahead_.begin();
      finished_ahead_.erase(finished_ahead_.begin());
    }
    active_.erase(job);
    if (active_.empty()) idle_cv_.notify_all();
  }
  Post(ready);
}

uint64_t ChangeScheduler::applied_version() const {
  std::lock_guard lock(mu_);
  return applied_version_;
}

uint64_t ChangeScheduler::assigned_version() const {
  std::lock_guard lock(mu_);
  return next_version_ - 1;
}

void ChangeScheduler::WaitIdle() {
  std::unique_lock lock(mu_);
  idle_cv_.wait(lock, [this] { return active_.empty(); });
}

}  // namespace bgkmap
