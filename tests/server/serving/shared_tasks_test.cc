// RunSharingWithPool (serving/shared_tasks.h): every task runs exactly once, on the caller or on
// a pool thread, and the call returns only when all have finished; offers that a pool runs late,
// or never, change nothing.
#include "serving/shared_tasks.h"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <thread>
#include <vector>

namespace bgkmap {
namespace {

std::vector<std::function<void()>> Counting(std::vector<std::atomic<int>>& runs) {
  std::vector<std::function<void()>> tasks;
  for (size_t i = 0; i < runs.size(); ++i) {
    tasks.push_back([&runs, i] {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      runs[i].fetch_add(1);
    });
  }
  return tasks;
}

TEST(SharedTasksTest, EveryTaskRunsOnceWithAPool) {
  boost::asio::thread_pool pool(3);
  for (int round = 0; round < 50; ++round) {
    std::vector<std::atomic<int>> runs(4);
    RunSharingWithPool(Counting(runs), [&pool](std::function<void()> fn) {
      boost::asio::post(pool, std::move(fn));
    });
    for (size_t i = 0; i < runs.size(); ++i) ASSERT_EQ(runs[i].load(), 1) << "task " << i;
  }
  pool.join();
}

TEST(SharedTasksTest, TheCallerRunsWhatNoPoolTookAndLateOffersDoNothing) {
  std::vector<std::function<void()>> offers;  // a pool that is busy until after the call
  std::vector<std::atomic<int>> runs(3);
  const std::thread::id caller = std::this_thread::get_id();
  std::vector<std::thread::id> ran_on(3);
  std::vector<std::function<void()>> tasks;
  for (size_t i = 0; i < runs.size(); ++i) {
    tasks.push_back([&, i] {
      ran_on[i] = std::this_thread::get_id();
      runs[i].fetch_add(1);
    });
  }
  RunSharingWithPool(tasks, [&offers](std::function<void()> fn) { offers.push_back(fn); });
  EXPECT_EQ(offers.size(), 2u);  // every task but the first is offered
  for (size_t i = 0; i < runs.size(); ++i) {
    EXPECT_EQ(runs[i].load(), 1);
    EXPECT_EQ(ran_on[i], caller);
  }
  tasks.clear();                                        // the caller's tasks are gone...
  for (std::function<void()>& offer : offers) offer();  // ...and the late offers touch nothing
  for (size_t i = 0; i < runs.size(); ++i) EXPECT_EQ(runs[i].load(), 1);
}

TEST(SharedTasksTest, NoTasksIsNothing) {
  int offered = 0;
  RunSharingWithPool({}, [&offered](std::function<void()>) { ++offered; });
  EXPECT_EQ(offered, 0);
}

}  // namespace
}  // namespace bgkmap
