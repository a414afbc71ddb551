// WatchHub without a server: changed tiles reach only the watchers of their region, coalesce
// per tile while a watcher is slow (one update carries every change since the last), wake a
// watcher only when something new is pending, and never after it unsubscribed.
#include "serving/watch_hub.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <thread>
#include <vector>

namespace bgkmap {
namespace {

std::vector<TileKey> TakeAll(WatchHub& hub, uint64_t id) {
  std::vector<TileKey> out;
  for (TileKey k; hub.Take(id, &k);) out.push_back(k);
  return out;
}

TEST(WatchHubTest, ChangesReachOnlyTheWatchersOfTheirRegionSmallestKeyFirst) {
  WatchHub hub;
  int woken_a = 0, woken_b = 0;
  const uint64_t a = hub.Subscribe({0, 0}, {9, 9}, [&] { ++woken_a; }, {});
  const uint64_t b = hub.Subscribe({10, 0}, {19, 9}, [&] { ++woken_b; }, {});
  EXPECT_EQ(hub.subscriber_count(), 2u);
  hub.Publish({{12, 3}, {3, 4}, {1, 9}, {-1, 0}, {5, 10}});
  EXPECT_EQ(woken_a, 1);
  EXPECT_EQ(woken_b, 1);
  EXPECT_EQ(TakeAll(hub, a), (std::vector<TileKey>{{1, 9}, {3, 4}}));
  EXPECT_EQ(TakeAll(hub, b), (std::vector<TileKey>{{12, 3}}));
  // Outside every region: nobody is woken.
  hub.Publish({{100, 100}});
  EXPECT_EQ(woken_a, 1);
  EXPECT_EQ(woken_b, 1);
}

TEST(WatchHubTest, ASlowWatcherGetsEachTileOnceAndIsWokenOnlyForNewOnes) {
  WatchHub hub;
  int woken = 0;
  const uint64_t id = hub.Subscribe({0, 0}, {9, 9}, [&] { ++woken; }, {});
  hub.Publish({{1, 1}, {2, 2}});
  hub.Publish({{1, 1}});  // already pending: coalesced, no wake
  hub.Publish({{2, 2}, {1, 1}});
  EXPECT_EQ(woken, 1);
  hub.Publish({{3, 3}});
  EXPECT_EQ(woken, 2);
  EXPECT_EQ(TakeAll(hub, id), (std::vector<TileKey>{{1, 1}, {2, 2}, {3, 3}}));
  TileKey k;
  EXPECT_FALSE(hub.Take(id, &k));
  hub.Publish({{1, 1}});  // taken, so pending again
  EXPECT_EQ(woken, 3);
  EXPECT_EQ(TakeAll(hub, id), (std::vector<TileKey>{{1, 1}}));
}

TEST(WatchHubTest, InitialAndAddedKeysArePendingWithoutAWake) {
  WatchHub hub;
  int woken = 0;
  const uint64_t id = hub.Subscribe({0, 0}, {9, 9}, [&] { ++woken; }, {{4, 4}, {2, 2}});
  hub.AddPending(id, {{7, 7}, {2, 2}});
  EXPECT_EQ(woken, 0);
  EXPECT_EQ(TakeAll(hub, id), (std::vector<TileKey>{{2, 2}, {4, 4}, {7, 7}}));
  hub.AddPending(id + 100, {{1, 1}});  // an unknown id: ignored
  EXPECT_EQ(woken, 0);
}

TEST(WatchHubTest, PublishBoxMarksTheWatchedPartOfTheBoxOnly) {
  WatchHub hub;
  int woken = 0;
  const uint64_t id = hub.Subscribe({0, 0}, {2, 2}, [&] { ++woken; }, {});
  hub.PublishBox({1, -5}, {10, 1});
  EXPECT_EQ(woken, 1);
  EXPECT_EQ(TakeAll(hub, id), (std::vector<TileKey>{{1, 0}, {1, 1}, {2, 0}, {2, 1}}));
  hub.PublishBox({5, 5}, {6, 6});  // outside: no wake
  EXPECT_EQ(woken, 1);
  // The whole map (a web map's events): a box far larger than any region stays cheap.
  const uint64_t all = hub.Subscribe({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX}, [] {}, {});
  hub.PublishBox({3, 3}, {3, 4});
  EXPECT_EQ(TakeAll(hub, all), (std::vector<TileKey>{{3, 3}, {3, 4}}));
}

TEST(WatchHubTest, NoWakeAfterUnsubscribe) {
  WatchHub hub;
  std::atomic<int> woken{0};
  const uint64_t id = hub.Subscribe({0, 0}, {9, 9}, [&] { ++woken; }, {});
  hub.Unsubscribe(id);
  EXPECT_EQ(hub.subscriber_count(), 0u);
  hub.Publish({{1, 1}});
  hub.PublishBox({0, 0}, {9, 9});
  EXPECT_EQ(woken.load(), 0);
  TileKey k;
  EXPECT_FALSE(hub.Take(id, &k));
}

TEST(WatchHubTest, PublishersAndTakersOnManyThreadsLoseNoChange) {
  WatchHub hub;
  std::atomic<int> wakes{0};
  const uint64_t id = hub.Subscribe({0, 0}, {99, 99}, [&] { ++wakes; }, {});
  std::vector<TileKey> taken;
  std::atomic<bool> done{false};
  std::thread taker([&] {
    TileKey k;
    while (!done.load()) {
      while (hub.Take(id, &k)) taken.push_back(k);
    }
    while (hub.Take(id, &k)) taken.push_back(k);
  });
  std::vector<std::thread> publishers;
  for (int t = 0; t < 4; ++t) {
    publishers.emplace_back([&hub, t] {
      for (int i = 0; i < 25; ++i) hub.Publish({{t * 25 + i, t}});
    });
  }
  for (std::thread& p : publishers) p.join();
  done.store(true);
  taker.join();
  std::sort(taken.begin(), taken.end());
  ASSERT_EQ(taken.size(), 100u);  // each tile was published once, so taken once
  for (int t = 0; t < 4; ++t) {
    for (int i = 0; i < 25; ++i) {
      EXPECT_TRUE(std::binary_search(taken.begin(), taken.end(), TileKey{t * 25 + i, t}));
    }
  }
  EXPECT_GE(wakes.load(), 1);
}

}  // namespace
}  // namespace bgkmap
