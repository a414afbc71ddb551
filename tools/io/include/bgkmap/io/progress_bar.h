// Progress on stderr for long command-line runs. On a terminal: one line redrawn in place (at
// most ~10 times a second) with a bar, count, rate and ETA. Otherwise (logs, CI): a plain line
// each time another 10% is done, so logs stay short.
//
// Thread-safe: Add()/Set() may be called from worker threads.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>

namespace bgkmap::io {

class ProgressBar {
 public:
  // `total` = 0 means unknown (no bar, percentage or ETA; count and rate only).
  ProgressBar(std::string label, uint64_t total, std::string unit = "items",
              std::FILE* out = stderr);
  ~ProgressBar();  // calls Finish()
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void Add(uint64_t n = 1);
  void Set(uint64_t done);
  // Prints the final state (once) and ends the terminal line.
  void Finish();

  // Bars made after this print nothing (a command line's --quiet).
  static void SilenceAll();

  // "1:02:03", "02:03"; "--:--" for a negative or non-finite number of seconds.
  static std::string FormatDuration(double seconds);

 private:
  using Clock = std::chrono::steady_clock;
  void Report(bool final);  // needs mu_
  std::string Line(double elapsed) const;

  std::mutex mu_;
  const std::string label_;
  const std::string unit_;
  const uint64_t total_;
  std::FILE* const out_;
  const bool tty_;
  const Clock::time_point start_;
  Clock::time_point last_draw_;
  uint64_t done_ = 0;
  int last_decile_ = 0;
  bool finished_ = false;
};

}  // namespace bgkmap::io
