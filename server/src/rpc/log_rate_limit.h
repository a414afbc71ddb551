// At most a few log lines a second of one kind (issue 25: unauthenticated calls were logged
// without a limit, 650 KB/s of log from one client). The lines left out are counted and the
// next line let through reports how many. Thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>

namespace bgkmap {

class LogRateLimit {
 public:
  using Clock = std::chrono::steady_clock;
  explicit LogRateLimit(uint32_t per_second) : per_second_(per_second) {}

  // True if a line may be logged at `now`; then `*suppressed` is the number of lines left out
  // since the last one let through (0 otherwise).
  bool Allow(Clock::time_point now, uint64_t* suppressed) {
    std::lock_guard lock(mu_);
    if (now - window_start_ >= std::chrono::seconds(1)) {
      window_start_ = now;
      in_window_ = 0;
    }
    if (in_window_ >= per_second_) {
      ++suppressed_;
      return false;
    }
    ++in_window_;
    *suppressed = suppressed_;
    suppressed_ = 0;
    return true;
  }
  bool Allow(uint64_t* suppressed) { return Allow(Clock::now(), suppressed); }

 private:
  const uint32_t per_second_;
  std::mutex mu_;
  Clock::time_point window_start_{};
  uint32_t in_window_ = 0;
  uint64_t suppressed_ = 0;
};

}  // namespace bgkmap
