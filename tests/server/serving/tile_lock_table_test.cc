// TileLockTable: per-tile exclusion, no contention between disjoint tiles, entries only while used.
#include "serving/tile_lock_table.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <thread>

namespace bgkmap {
namespace {

using namespace std::chrono_literals;

TEST(TileLockTableTest, WriterExcludesReadersOfItsTilesOnly) {
  TileLockTable table;
  const TileKey a{0, 0}, b{5, -3};
  std::atomic<bool> reader_in{false};
  TileLockTable::Guard writer = table.Lock(std::vector<TileKey>{a}, {});
  // A reader of another tile is not held up.
  { TileLockTable::Guard other = table.Lock({}, std::vector<TileKey>{b}); }
  std::thread reader([&] {
    TileLockTable::Guard g = table.Lock({}, std::vector<TileKey>{b, a});
    reader_in = true;
  });
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(reader_in.load());
  writer.Release();
  reader.join();
  EXPECT_TRUE(reader_in.load());
}

TEST(TileLockTableTest, EntriesLiveOnlyWhileUsed) {
  TileLockTable table;
  {
    TileLockTable::Guard g = table.LockRange({-10, -10}, {9, 9});
    EXPECT_EQ(table.entry_count(), 400u);
    TileLockTable::Guard more = table.Lock({}, std::vector<TileKey>{{0, 0}, {100, 100}});
    EXPECT_EQ(table.entry_count(), 401u);
  }
  EXPECT_EQ(table.entry_count(), 0u);
}

TEST(TileLockTableTest, OpposingOrdersDoNotDeadlock) {
  TileLockTable table;
  std::vector<TileKey> up, down;
  for (int i = 0; i < 50; ++i) up.push_back({i, i % 7});
  down.assign(up.rbegin(), up.rend());
  std::atomic<int> done{0};
  auto worker = [&](const std::vector<TileKey>& keys, bool exclusive) {
    for (int n = 0; n < 300; ++n) {
      TileLockTable::Guard g = exclusive ? table.Lock(keys, {}) : table.Lock({}, keys);
    }
    ++done;
  };
  std::thread t1(worker, up, true), t2(worker, down, true), t3(worker, up, false),
      t4(worker, down, false);
  t1.join();
  t2.join();
  t3.join();
  t4.join();
  EXPECT_EQ(done.load(), 4);
  EXPECT_EQ(table.entry_count(), 0u);
}

// A point query tries the tiles without waiting (and leaves the query to a pool thread if a
// change holds one): it must fail while any of them is held exclusively, succeed beside other
// readers, and hold nothing after failing.
TEST(TileLockTableTest, TryLockSharedNeverWaitsAndHoldsNothingWhenItFails) {
  TileLockTable table;
  const std::vector<TileKey> both = {{0, 0}, {1, 0}};
  {
    TileLockTable::Guard reader = table.Lock({}, std::vector<TileKey>{both[0]});
    EXPECT_TRUE(table.TryLockShared(both).has_value());  // readers share
  }
  TileLockTable::Guard writer = table.Lock(std::vector<TileKey>{both[1]}, {});
  EXPECT_FALSE(table.TryLockShared(both).has_value());
  EXPECT_EQ(table.entry_count(), 1u);  // only the writer's
  // The tile it took before failing is free: a writer takes it (would block forever if not).
  std::thread other_writer([&] { TileLockTable::Guard g = table.Lock(both, {}); });
  writer.Release();
  other_writer.join();
  std::optional<TileLockTable::Guard> shared = table.TryLockShared(both);
  ASSERT_TRUE(shared.has_value());
  EXPECT_EQ(table.entry_count(), 2u);
  shared->Release();
  EXPECT_EQ(table.entry_count(), 0u);
}

}  // namespace
}  // namespace bgkmap
