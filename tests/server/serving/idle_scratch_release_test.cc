// IdleScratchRelease: once the pool has been idle, the release runs on each of its threads and
// the trim once after them; work keeps postponing it; nothing starts after destruction.
#include "serving/idle_scratch_release.h"

#include <gtest/gtest.h>

#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <functional>
#include <future>
#include <mutex>
#include <set>
#include <thread>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/core/thread_scratch.h"

namespace bgkmap {
namespace {

using namespace std::chrono_literals;

// What the release and the trim saw, from the pool's threads.
struct Seen {
  std::mutex mu;
  std::set<std::thread::id> released_on;
  int releases = 0;
  int trims = 0;
  std::pair<int, int> Counts() {
    std::lock_guard lock(mu);
    return {releases, trims};
  }
  // The release and the trim that count here.
  std::function<void()> Release() {
    return [this] {
      std::lock_guard lock(mu);
      released_on.insert(std::this_thread::get_id());
      ++releases;
    };
  }
  std::function<void()> Trim() {
    return [this] {
      std::lock_guard lock(mu);
      ++trims;
    };
  }
};

// Polls `done` until it holds or 60 s pass (CI's machine may be loaded).
template <typename Done>
bool WaitFor(Done done) {
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

TEST(IdleScratchReleaseTest, ReleasesOnEveryThreadThenTrimsOnceWhenIdle) {
  constexpr size_t kThreads = 3;
  boost::asio::thread_pool pool(kThreads);
  Seen seen;
  {
    IdleScratchRelease release(pool, kThreads, 20ms, seen.Release(), seen.Trim());
    EXPECT_EQ(seen.Counts(), std::make_pair(0, 0)) << "nothing before any work";
    release.Touch();
    ASSERT_TRUE(WaitFor([&] { return seen.Counts().second == 1; }));
    {
      std::lock_guard lock(seen.mu);
      EXPECT_EQ(seen.releases, static_cast<int>(kThreads));
      EXPECT_EQ(seen.released_on.size(), kThreads) << "each thread released its own";
    }
    // Idle again without new work: no second round.
    std::this_thread::sleep_for(100ms);
    EXPECT_EQ(seen.Counts(), std::make_pair(static_cast<int>(kThreads), 1));
    // New work, a new round.
    release.Touch();
    ASSERT_TRUE(WaitFor([&] { return seen.Counts().second == 2; }));
  }
  pool.join();
  EXPECT_EQ(seen.Counts(), std::make_pair(2 * static_cast<int>(kThreads), 2));
}

TEST(IdleScratchReleaseTest, WorkKeepsPostponingTheRelease) {
  boost::asio::thread_pool pool(2);
  Seen seen;
  {
    // An idle time far above the gap between touches, however loaded the machine.
    IdleScratchRelease release(pool, 2, 2s, seen.Release(), seen.Trim());
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - start < 300ms) {
      release.Touch();
      std::this_thread::sleep_for(10ms);
    }
    // 300 ms of work, the last touch just now: 2 s of idle are not over.
    EXPECT_EQ(seen.Counts(), std::make_pair(0, 0));
  }  // destroyed: the pending timer is cancelled
  pool.join();
  EXPECT_EQ(seen.Counts(), std::make_pair(0, 0)) << "no release after destruction";
}

// A server shutting down joins its workers while the served map (and this) still exist: the
// pending timer must not keep the pool busy until the idle time has passed.
TEST(IdleScratchReleaseTest, StoppedThePoolJoinsWithoutWaitingForTheIdleTime) {
  boost::asio::thread_pool pool(2);
  Seen seen;
  IdleScratchRelease release(pool, 2, 90s, seen.Release(), seen.Trim());
  release.Touch();  // a timer of 90 s is pending
  release.Stop();
  release.Touch();  // nothing is armed after a stop
  std::future<void> joined = std::async(std::launch::async, [&] { pool.join(); });
  ASSERT_EQ(joined.wait_for(30s), std::future_status::ready) << "the pool waited for the timer";
  EXPECT_EQ(seen.Counts(), std::make_pair(0, 0));
}

TEST(IdleScratchReleaseTest, TheDefaultReleaseHandsBackTheEngineScratch) {
  boost::asio::thread_pool pool(1);
  // A scan on the pool's thread leaves the engine's scratch there.
  std::promise<size_t> scanned;
  boost::asio::post(pool, [&] {
    MapParams p;
    p.resolution = 0.1;
    std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(p)).value();
    std::vector<Point3f> points;
    for (int i = 0; i < 4000; ++i) {
      points.push_back({0.01f * static_cast<float>(i % 400) - 2, 0.1f * (i / 400) - 0.5f, -1});
    }
    Pose at;
    at.translation = Eigen::Vector3d(0, 0, 1);
    EXPECT_TRUE(map->IntegrateScan(points, at, false, 1).ok());
    scanned.set_value(ThreadScratchBytes());
  });
  ASSERT_GT(scanned.get_future().get(), 0u);
  std::promise<size_t> after;
  {
    IdleScratchRelease release(pool, 1, 10ms, {}, [&] { after.set_value(ThreadScratchBytes()); });
    release.Touch();
    std::future<size_t> bytes = after.get_future();
    ASSERT_EQ(bytes.wait_for(60s), std::future_status::ready);
    EXPECT_EQ(bytes.get(), 0u) << "the trim runs on the thread that released last";
  }
  pool.join();
}

}  // namespace
}  // namespace bgkmap
