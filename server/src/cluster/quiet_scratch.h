// The engine's scratch of a thread that integrates by itself: a cluster shard's log reader
// prepares and integrates every scan of its partitions on its own thread. Once it has had
// nothing to integrate for a while, its buffers go back to the system, as a single server's
// workers' do (IdleScratchRelease, serving/). One per thread, used only from that thread.
#pragma once

#include <chrono>
#include <functional>

namespace bgkmap {

class QuietScratch {
 public:
  using Clock = std::chrono::steady_clock;

  // `release` runs on the calling thread; by default ReturnThreadScratch (heap_policy.h).
  explicit QuietScratch(std::chrono::milliseconds idle, std::function<void()> release = {});

  // The thread integrated something at `now`: its buffers are warm again.
  void Worked(Clock::time_point now);
  // Called between waits for work. Releases once per quiet spell of at least `idle` since the
  // last Worked(); true when it did.
  bool Quiet(Clock::time_point now);

 private:
  const std::chrono::milliseconds idle_;
  std::function<void()> release_;
  Clock::time_point last_work_{};
  bool warm_ = false;  // worked since the last release
};

}  // namespace bgkmap
