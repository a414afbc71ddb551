#include "serving/idle_scratch_release.h"

#include <atomic>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <condition_variable>
#include <mutex>

#include "bgkmap/core/thread_scratch.h"
#include "bgkmap/server/heap_policy.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

// One release on every thread: each task waits (briefly) for the others to arrive, so that no
// free thread takes two of them; the last to arrive runs `after`.
struct Round {
  std::mutex mu;
  std::condition_variable cv;
  size_t arrived = 0;
};

constexpr auto kRoundWait = std::chrono::milliseconds(100);

}  // namespace

struct IdleScratchRelease::State {
  State(boost::asio::thread_pool& p, size_t n, std::chrono::milliseconds i)
      : pool(p), threads(std::max<size_t>(1, n)), idle(i), timer(p) {}
  boost::asio::thread_pool& pool;
  const size_t threads;
  const std::chrono::milliseconds idle;
  std::function<void()> before, release, after;
  std::atomic<int64_t> last_touch_ns{0};
  std::atomic<bool> armed{false};
  std::mutex mu;  // timer, stopped
  boost::asio::steady_timer timer;
  bool stopped = false;
};

namespace {

void ReleaseOnEveryThread(const std::shared_ptr<IdleScratchRelease::State>& st);

void Arm(const std::shared_ptr<IdleScratchRelease::State>& st, std::chrono::nanoseconds in);

void OnTimer(const std::shared_ptr<IdleScratchRelease::State>& st) {
  // Disarmed before the clock is read: a Touch from here on arms a timer of its own.
  st->armed.store(false);
  const std::chrono::nanoseconds since(NowNs() - st->last_touch_ns.load());
  if (since < st->idle) {
    if (!st->armed.exchange(true)) Arm(st, st->idle - since);
    return;
  }
  ReleaseOnEveryThread(st);
}

void Arm(const std::shared_ptr<IdleScratchRelease::State>& st, std::chrono::nanoseconds in) {
  std::lock_guard lock(st->mu);
  if (st->stopped) return;
  st->timer.expires_after(in);
  st->timer.async_wait([st](const boost::system::error_code& ec) {
    if (!ec) OnTimer(st);
  });
}

void ReleaseOnEveryThread(const std::shared_ptr<IdleScratchRelease::State>& st) {
  st->before();
  auto round = std::make_shared<Round>();
  for (size_t i = 0; i < st->threads; ++i) {
    boost::asio::post(st->pool, [st, round] {
      st->release();
      std::unique_lock lock(round->mu);
      if (++round->arrived == st->threads) {
        round->cv.notify_all();
        lock.unlock();
        st->after();
        return;
      }
      round->cv.wait_for(lock, kRoundWait, [&] { return round->arrived == st->threads; });
    });
  }
}

}  // namespace

IdleScratchRelease::IdleScratchRelease(boost::asio::thread_pool& pool, size_t threads,
                                       std::chrono::milliseconds idle,
                                       std::function<void()> release, std::function<void()> after)
    : state_(std::make_shared<State>(pool, threads, idle)) {
  // By default the buffers go back to the system as they are freed (heap_policy.h).
  const bool returning = !after;
  state_->before = returning ? [] { BeginReturningFreedMemory(); } : std::function<void()>([] {});
  state_->release = release ? std::move(release) : [] { ReleaseThreadScratch(); };
  state_->after = after ? std::move(after) : [] { EndReturningFreedMemory(); };
}

IdleScratchRelease::~IdleScratchRelease() { Stop(); }

void IdleScratchRelease::Stop() {
  std::lock_guard lock(state_->mu);
  state_->stopped = true;
  state_->timer.cancel();  // the pending wait ends now (operation_aborted): the pool is free
}

void IdleScratchRelease::Touch() {
  state_->last_touch_ns.store(NowNs());
  if (!state_->armed.exchange(true)) Arm(state_, state_->idle);
}

}  // namespace bgkmap
