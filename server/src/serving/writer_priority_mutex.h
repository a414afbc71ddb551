// A shared mutex that lets a waiting exclusive locker in ahead of new shared lockers. Scans hold
// the map gate shared back to back; with a reader-preferring lock (glibc's default) a map-wide
// operation such as Info could wait forever while robots stream.
#pragma once

#include <condition_variable>
#include <mutex>

namespace bgkmap {

class WriterPriorityMutex {
 public:
  void lock() {
    std::unique_lock l(mu_);
    ++waiting_writers_;
    cv_.wait(l, [this] { return !writer_ && readers_ == 0; });
    --waiting_writers_;
    writer_ = true;
  }
  void unlock() {
    {
      std::lock_guard l(mu_);
      writer_ = false;
    }
    cv_.notify_all();
  }
  void lock_shared() {
    std::unique_lock l(mu_);
    cv_.wait(l, [this] { return !writer_ && waiting_writers_ == 0; });
    ++readers_;
  }
  void unlock_shared() {
    bool last = false;
    {
      std::lock_guard l(mu_);
      last = --readers_ == 0;
    }
    if (last) cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  int readers_ = 0;
  int waiting_writers_ = 0;
  bool writer_ = false;
};

}  // namespace bgkmap
