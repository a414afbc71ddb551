// TileChangeLog (region deltas): the tiles of a box changed after a version, per column of the
// sorted record, with the blocks changed after it (exact for the recent history, a superset
// beyond); nothing answered below the version the server started at; and the scheduler records
// a change, with its blocks, before the applied version covers it.
#include "serving/tile_change_log.h"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio/thread_pool.hpp>

#include "serving/change_scheduler.h"

namespace bgkmap {
namespace {

using Keys = std::vector<TileKey>;

Keys KeysOf(const std::optional<std::vector<ChangedTile>>& changed) {
  Keys out;
  for (const ChangedTile& c : changed.value()) out.push_back(c.key);
  return out;
}

// Block n of a tile: (n % 16, n / 16).
TileBlocks Block(int n) {
  TileBlocks b;
  b.AddRect(n % kTileBlocksPerSide, n / kTileBlocksPerSide, n % kTileBlocksPerSide,
            n / kTileBlocksPerSide);
  return b;
}

// The blocks the log names for tile (0, 0) after `since`.
TileBlocks BlocksAfter(const TileChangeLog& log, uint64_t since) {
  const std::vector<ChangedTile> changed = log.ChangedSince({0, 0}, {0, 0}, since).value();
  return changed.empty() ? TileBlocks() : changed.front().blocks;
}

TEST(TileChangeLogTest, ListsTheTilesOfTheBoxChangedAfterAVersion) {
  TileChangeLog log(0, NewHistoryId());
  log.Record(1, {{0, 0}, {1, 0}, {5, 5}, {-2, 1}});
  log.Record(2, {{1, 0}, {1, 3}, {1, -1}});
  log.Record(3, {{0, 2}});
  EXPECT_EQ(KeysOf(log.ChangedSince({-1, -1}, {1, 2}, 0)), (Keys{{0, 0}, {0, 2}, {1, -1}, {1, 0}}));
  EXPECT_EQ(KeysOf(log.ChangedSince({-1, -1}, {1, 2}, 1)), (Keys{{0, 2}, {1, -1}, {1, 0}}));
  EXPECT_EQ(KeysOf(log.ChangedSince({-1, -1}, {1, 2}, 3)), Keys{});
  EXPECT_EQ(KeysOf(log.ChangedSince({-2, 1}, {-2, 1}, 0)), (Keys{{-2, 1}}));
  EXPECT_EQ(KeysOf(log.ChangedSince({2, 0}, {4, 9}, 0)), Keys{});
  // A later change of a tile replaces its version; an earlier one (never sent) does not.
  log.Record(1, {{0, 2}});
  EXPECT_EQ(KeysOf(log.ChangedSince({0, 2}, {0, 2}, 2)), (Keys{{0, 2}}));
}

TEST(TileChangeLogTest, AVersionBelowTheStartIsNotAnswered) {
  TileChangeLog log(7, NewHistoryId());
  log.Record(8, {{0, 0}});
  EXPECT_FALSE(log.ChangedSince({0, 0}, {0, 0}, 6).has_value());
  EXPECT_EQ(KeysOf(log.ChangedSince({0, 0}, {0, 0}, 7)), (Keys{{0, 0}}));
  EXPECT_NE(log.history_id(), 0u);
  EXPECT_NE(NewHistoryId(), NewHistoryId());
}

TEST(TileChangeLogTest, NamesTheBlocksChangedAfterAVersion) {
  TileChangeLog log(0, NewHistoryId());
  log.Record(1, {{0, 0}}, {Block(0)});
  log.Record(2, {{0, 0}}, {Block(200)});
  log.Record(3, {{0, 0}, {0, 1}}, {Block(200), TileBlocks()});
  EXPECT_EQ(BlocksAfter(log, 0), Block(0) | Block(200));
  EXPECT_EQ(BlocksAfter(log, 1), Block(200));
  EXPECT_EQ(BlocksAfter(log, 3), TileBlocks());
  // A tile changed with no block named (a write tile the scan did not touch) is listed with none.
  EXPECT_EQ(log.ChangedSince({0, 1}, {0, 1}, 0).value(),
            (std::vector<ChangedTile>{{{0, 1}, TileBlocks()}}));
  // A change recorded without blocks (a clear, an import, a correction): the whole tile.
  log.Record(4, {{0, 0}});
  EXPECT_EQ(BlocksAfter(log, 3), TileBlocks::All());
  EXPECT_EQ(BlocksAfter(log, 4), TileBlocks());
}

// More changes than the history holds: the oldest merge, so an old `since` may name more blocks
// than changed, never fewer, and the recent ones stay exact.
TEST(TileChangeLogTest, AMergedHistoryNamesASupersetNeverLess) {
  TileChangeLog log(0, NewHistoryId());
  constexpr int kChanges = 3 * TileChangeLog::kHistory;
  // Blocks 14 apart, so the changes fall in every word of the mask.
  for (int v = 1; v <= kChanges; ++v) log.Record(v, {{0, 0}}, {Block(14 * v)});
  for (int since = 0; since <= kChanges; ++since) {
    TileBlocks exact;
    for (int v = since + 1; v <= kChanges; ++v) exact |= Block(14 * v);
    const TileBlocks named = BlocksAfter(log, since);
    EXPECT_TRUE(named.Contains(exact)) << "since " << since;
    if (since >= kChanges - (TileChangeLog::kHistory - 1)) {
      EXPECT_EQ(named, exact) << since;
    }
  }
}

// Mutation checked: recording after Finish() (with on_tiles_changed) fails this test.
TEST(TileChangeLogTest, TheSchedulerRecordsAChangeBeforeTheAppliedVersionCoversIt) {
  boost::asio::thread_pool pool(2);
  std::atomic<bool> covered_early{false};
  ChangeScheduler* self = nullptr;
  std::atomic<int> with_blocks{0};
  ChangeScheduler scheduler(
      pool, {},
      [&](uint64_t version, const std::vector<TileKey>&, const std::vector<TileBlocks>& blocks) {
        if (self->applied_version() >= version) covered_early = true;
        if (blocks == std::vector<TileBlocks>{Block(0) | Block(1)}) ++with_blocks;
      });
  self = &scheduler;
  for (int i = 0; i < 50; ++i) {
    scheduler.Submit(ChangeScheduler::TileChange{{{i % 3, 0}}, {}}, [](uint64_t) {
      return ChangeScheduler::Done{{{0, 0}}, {}, {Block(0) | Block(1)}};
    });
  }
  scheduler.WaitIdle();
  EXPECT_FALSE(covered_early.load());
  EXPECT_EQ(with_blocks.load(), 50);
}

}  // namespace
}  // namespace bgkmap
