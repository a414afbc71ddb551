#include "cluster/quiet_scratch.h"

#include "bgkmap/server/heap_policy.h"

namespace bgkmap {

QuietScratch::QuietScratch(std::chrono::milliseconds idle, std::function<void()> release)
    : idle_(idle), release_(release ? std::move(release) : [] { ReturnThreadScratch(); }) {}

void QuietScratch::Worked(Clock::time_point now) {
  last_work_ = now;
  warm_ = true;
}

bool QuietScratch::Quiet(Clock::time_point now) {
  if (!warm_ || now - last_work_ < idle_) return false;
  release_();
  warm_ = false;
  return true;
}

}  // namespace bgkmap
