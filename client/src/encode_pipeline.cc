#include "encode_pipeline.h"

#include <algorithm>
#include <utility>

namespace bgkmap::client_codec {

EncodePipeline::EncodePipeline(ScanEncoding encoding, int threads, int ahead, WriteFn write)
    : encoding_(std::move(encoding)),
      ahead_(static_cast<size_t>(std::max(ahead, 1))),
      write_(std::move(write)) {
  for (int i = 0; i < std::max(threads, 1); ++i) threads_.emplace_back([this] { EncodeLoop(); });
  threads_.emplace_back([this] { WriteLoop(); });
}

EncodePipeline::~EncodePipeline() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  changed_.notify_all();
  for (std::thread& t : threads_) t.join();
}

bool EncodePipeline::Submit(const ScanData& scan) {
  auto job = std::make_unique<Job>();
  job->points.assign(scan.points.begin(), scan.points.end());
  job->header = scan;
  job->header.points = job->points;
  job->out.robot_id = scan.robot_id;
  job->out.sequence = scan.sequence;
  std::unique_lock lock(mu_);
  changed_.wait(lock, [&] { return failed_ || closed_ || jobs_.size() < ahead_; });
  if (failed_ || closed_) return false;
  job->index = submitted_++;
  to_encode_.push_back(job.get());
  jobs_.push_back(std::move(job));
  lock.unlock();
  changed_.notify_all();
  return true;
}

void EncodePipeline::Close() {
  std::unique_lock lock(mu_);
  closed_ = true;
  changed_.notify_all();
  changed_.wait(lock, [&] { return jobs_.empty() || stopping_; });
}

bool EncodePipeline::broken() const {
  std::lock_guard lock(mu_);
  return failed_;
}

void EncodePipeline::EncodeLoop() {
  std::unique_lock lock(mu_);
  for (;;) {
    changed_.wait(lock, [&] { return stopping_ || !to_encode_.empty(); });
    if (stopping_) return;
    Job* job = to_encode_.front();
    to_encode_.pop_front();
    if (!failed_) {  // after a failed write the scan is dropped unencoded
      lock.unlock();
      job->out.here =
          EncodeHinted(job->header, job->index, encoding_, &order_hint_, &job->out.message);
      job->points = {};
      job->header.points = {};
      lock.lock();
    }
    job->encoded = true;
    changed_.notify_all();
  }
}

void EncodePipeline::WriteLoop() {
  std::unique_lock lock(mu_);
  for (;;) {
    changed_.wait(lock, [&] { return stopping_ || (!jobs_.empty() && jobs_.front()->encoded); });
    if (stopping_) return;
    // Still counted in jobs_ while it is written: Close() returns only after the write.
    Job* job = jobs_.front().get();
    if (!failed_) {
      lock.unlock();
      const bool ok = write_(job->out);
      lock.lock();
      failed_ = failed_ || !ok;
    }
    jobs_.pop_front();
    changed_.notify_all();
  }
}

}  // namespace bgkmap::client_codec
