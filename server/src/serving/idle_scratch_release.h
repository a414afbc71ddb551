// Hands the engine's per-thread scratch buffers back (bgkmap/core/thread_scratch.h) on the
// threads of the worker pool once no change has run on it for a while, and returns the freed
// memory to the system (bgkmapd keeps freed memory in its heap otherwise: heap_policy.h). A robot
// streaming keeps the buffers warm; a server left idle keeps its map, not the megabytes of its
// last dense scans on every worker. Best effort: a task of the release round may land on a
// thread that already took one while another thread is busy; that thread keeps its buffers
// until the next round.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>

namespace bgkmap {

class IdleScratchRelease {
 public:
  // After `idle` without a Touch(), `release` runs once on each of the pool's `threads` threads
  // (as far as they are free), and then `after` once. By default ReleaseThreadScratch, with the
  // heap returning what is freed meanwhile (Begin/EndReturningFreedMemory, heap_policy.h); a
  // test passes its own.
  IdleScratchRelease(boost::asio::thread_pool& pool, size_t threads, std::chrono::milliseconds idle,
                     std::function<void()> release = {}, std::function<void()> after = {});
  ~IdleScratchRelease();  // Stop()
  IdleScratchRelease(const IdleScratchRelease&) = delete;
  IdleScratchRelease& operator=(const IdleScratchRelease&) = delete;

  // Work ran on the pool: the idle clock starts again. Cheap (an atomic store) while a round is
  // pending.
  void Touch();
  // No release starts afterwards, and the pending timer is cancelled, so the pool can be joined
  // without waiting for the idle time. Touch() then does nothing.
  void Stop();

  struct State;  // shared with the timer's and the release round's tasks (the .cc)

 private:
  std::shared_ptr<State> state_;
};

}  // namespace bgkmap
