// TileChangeLog (region deltas): the tiles of a box changed after a version, per column of the
// sorted record; nothing answered below the version the server started at; and the scheduler
// records a change before the applied version covers it.
#include "serving/tile_change_log.h"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio/thread_pool.hpp>

#include "serving/change_scheduler.h"

namespace bgkmap {
namespace {

using Keys = std::vector<TileKey>;

TEST(TileChangeLogTest, ListsTheTilesOfTheBoxChangedAfterAVersion) {
  TileChangeLog log(0, NewHistoryId());
  log.Record(1, {{0, 0}, {1, 0}, {5, 5}, {-2, 1}});
  log.Record(2, {{1, 0}, {1, 3}, {1, -1}});
  log.Record(3, {{0, 2}});
  EXPECT_EQ(*log.ChangedSince({-1, -1}, {1, 2}, 0), (Keys{{0, 0}, {0, 2}, {1, -1}, {1, 0}}));
  EXPECT_EQ(*log.ChangedSince({-1, -1}, {1, 2}, 1), (Keys{{0, 2}, {1, -1}, {1, 0}}));
  EXPECT_EQ(*log.ChangedSince({-1, -1}, {1, 2}, 3), Keys{});
  EXPECT_EQ(*log.ChangedSince({-2, 1}, {-2, 1}, 0), (Keys{{-2, 1}}));
  EXPECT_EQ(*log.ChangedSince({2, 0}, {4, 9}, 0), Keys{});
  // A later change of a tile replaces its version; an earlier one (never sent) does not.
  log.Record(1, {{0, 2}});
  EXPECT_EQ(*log.ChangedSince({0, 2}, {0, 2}, 2), (Keys{{0, 2}}));
}

TEST(TileChangeLogTest, AVersionBelowTheStartIsNotAnswered) {
  TileChangeLog log(7, NewHistoryId());
  log.Record(8, {{0, 0}});
  EXPECT_FALSE(log.ChangedSince({0, 0}, {0, 0}, 6).has_value());
  EXPECT_EQ(*log.ChangedSince({0, 0}, {0, 0}, 7), (Keys{{0, 0}}));
  EXPECT_NE(log.history_id(), 0u);
  EXPECT_NE(NewHistoryId(), NewHistoryId());
}

// Mutation checked: recording after Finish() (with on_tiles_changed) fails this test.
TEST(TileChangeLogTest, TheSchedulerRecordsAChangeBeforeTheAppliedVersionCoversIt) {
  boost::asio::thread_pool pool(2);
  std::atomic<bool> covered_early{false};
  ChangeScheduler* self = nullptr;
  ChangeScheduler scheduler(pool, {}, [&](uint64_t version, const std::vector<TileKey>&) {
    if (self->applied_version() >= version) covered_early = true;
  });
  self = &scheduler;
  for (int i = 0; i < 50; ++i) {
    scheduler.Submit(ChangeScheduler::TileChange{{{i % 3, 0}}, {}}, [](uint64_t) {
      return ChangeScheduler::Done{{{0, 0}}, {}};
    });
  }
  scheduler.WaitIdle();
  EXPECT_FALSE(covered_early.load());
}

}  // namespace
}  // namespace bgkmap
