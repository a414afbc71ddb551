#include "scan_read_ahead.h"

#include <algorithm>
#include <utility>

namespace bgkmap::cli {

ScanReadAhead::ScanReadAhead(const ScanSource& source, size_t first, size_t depth)
    : source_(source),
      depth_(std::max<size_t>(depth, 1)),
      thread_([this, first] { ReadLoop(first); }) {}

ScanReadAhead::~ScanReadAhead() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

Result<SourceScan> ScanReadAhead::Next() {
  std::unique_lock lock(mu_);
  changed_.wait(lock, [&] { return !ready_.empty(); });
  Result<SourceScan> scan = std::move(ready_.front());
  ready_.pop_front();
  lock.unlock();
  changed_.notify_all();
  return scan;
}

void ScanReadAhead::ReadLoop(size_t first) {
  for (size_t k = first; k < source_.size(); ++k) {
    Result<SourceScan> scan = source_.Read(k);  // without the lock: Next() takes earlier ones
    const bool failed = !scan.ok();
    std::unique_lock lock(mu_);
    changed_.wait(lock, [&] { return stopping_ || ready_.size() < depth_; });
    if (stopping_) return;
    ready_.push_back(std::move(scan));
    lock.unlock();
    changed_.notify_all();
    if (failed) return;
  }
}

}  // namespace bgkmap::cli
