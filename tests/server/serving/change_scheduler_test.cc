// ChangeScheduler's ordering by kind: disjoint scans run side by side, a scan waits for the
// writer of a tile it reads, exclusive changes and barriers wait for everything before them and
// hold back everything after, and only barriers take no version.
#include "serving/change_scheduler.h"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <future>
#include <mutex>
#include <thread>

namespace bgkmap {
namespace {

using Done = ChangeScheduler::Done;

class ChangeSchedulerTest : public ::testing::Test {
 protected:
  ChangeScheduler::Work Record(int id, std::chrono::milliseconds hold = {}) {
    return [this, id, hold](uint64_t version) {
      {
        std::lock_guard lock(mu_);
        started_.push_back(id);
        versions_.push_back(version);
      }
      const int now = ++running_;
      int peak = peak_.load();
      while (now > peak && !peak_.compare_exchange_weak(peak, now)) {
      }
      std::this_thread::sleep_for(hold);
      --running_;
      return Done{};
    };
  }

  boost::asio::thread_pool pool_{4};
  ChangeScheduler scheduler_{pool_, {}};
  std::mutex mu_;
  std::vector<int> started_;
  std::vector<uint64_t> versions_;
  std::atomic<int> running_{0}, peak_{0};
};

TEST_F(ChangeSchedulerTest, VersionsFollowAdmissionAndBarriersTakeNone) {
  using TC = ChangeScheduler::TileChange;
  EXPECT_EQ(scheduler_.Submit(TC{{{0, 0}}, {}}, Record(1)), 1u);
  EXPECT_EQ(scheduler_.Submit(ChangeScheduler::Barrier{}, Record(2)), 0u);
  EXPECT_EQ(scheduler_.Submit(ChangeScheduler::ExclusiveChange{}, Record(3)), 2u);
  EXPECT_EQ(scheduler_.Submit(TC{{{1, 0}}, {}}, Record(4)), 3u);
  scheduler_.WaitIdle();
  EXPECT_EQ(started_, (std::vector<int>{1, 2, 3, 4}));
  // The barrier ran with the applied version: every change admitted before it.
  EXPECT_EQ(versions_, (std::vector<uint64_t>{1, 1, 2, 3}));
  EXPECT_EQ(scheduler_.applied_version(), 3u);
}

// Mutation checked: making a read tile depend on nothing (DependenciesLocked) fails the order.
TEST_F(ChangeSchedulerTest, ReaderWaitsForTheWriterAndExclusiveHoldsBackLaterScans) {
  using TC = ChangeScheduler::TileChange;
  const auto slow = std::chrono::milliseconds(100);
  scheduler_.Submit(TC{{{0, 0}}, {}}, Record(1, slow));  // writes A
  scheduler_.Submit(TC{{{5, 5}}, {{0, 0}}}, Record(2));  // reads A: after 1
  scheduler_.Submit(ChangeScheduler::ExclusiveChange{}, Record(3));
  scheduler_.Submit(TC{{{9, 9}}, {}}, Record(4));  // disjoint, but after the exclusive change
  scheduler_.WaitIdle();
  EXPECT_EQ(started_, (std::vector<int>{1, 2, 3, 4}));
}

TEST_F(ChangeSchedulerTest, DisjointScansRunSideBySide) {
  using TC = ChangeScheduler::TileChange;
  std::promise<void> both;
  std::atomic<int> arrived{0};
  std::shared_future<void> shared = both.get_future().share();
  // Each waits (bounded) until the other has started: only possible if they run together.
  auto meet_shared = [&](uint64_t) {
    if (++arrived == 2) both.set_value();
    EXPECT_EQ(shared.wait_for(std::chrono::seconds(10)), std::future_status::ready);
    return Done{};
  };
  scheduler_.Submit(TC{{{0, 0}}, {}}, meet_shared);
  scheduler_.Submit(TC{{{1, 0}}, {}}, meet_shared);
  scheduler_.WaitIdle();
  EXPECT_EQ(arrived.load(), 2);
}

}  // namespace
}  // namespace bgkmap
