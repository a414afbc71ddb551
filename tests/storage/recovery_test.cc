// Drops the in-memory map (and the store handle) mid-run and rebuilds it from the store: the
// result must be bitwise the map of an uninterrupted run.
#include "bgkmap/storage/recovery.h"

#include <gtest/gtest.h>

#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::Checkpointer;
using testing::MakeScan;
using testing::MapsIdentical;
using testing::NewMap;
using testing::SmallParams;
using testing::StatisticsIdentical;
using testing::TempDir;

// One change of a run: a scan of a robot, or a clear.
struct Change {
  int robot = 0;  // -1: clear
  int index = 0;
};

// Three robots on overlapping lanes, with two clears.
std::vector<Change> Script(int scans) {
  std::vector<Change> changes;
  for (int i = 0; i < scans; ++i) {
    changes.push_back({i % 3, i / 3});
    if (i == scans / 3 || i == 2 * scans / 3) changes.push_back({-1, i});
  }
  return changes;
}

CellBox ClearBoxOf(int index) { return {{index, -4}, {index + 12, 9}}; }

// Runs `changes` into `map` (and, if given, the store's log with checkpoints after the listed
// versions), as a server would.
void RunChanges(const MapParams& params, const std::vector<Change>& changes, TerrainMap& map,
                TileStore* store, const std::set<uint64_t>& checkpoints_after) {
  Checkpointer checkpointer;
  uint64_t version = map.version();
  for (const Change& c : changes) {
    ++version;
    if (c.robot < 0) {
      map.set_version(version - 1);
      checkpointer.MarkDirty(map.ClearBox(ClearBoxOf(c.index)));
      if (store) {
        ASSERT_TRUE(store->log().Append(LogRecord::Clear(version, ClearBoxOf(c.index))).ok());
      }
    } else {
      const auto scan = MakeScan(params, c.robot, c.index);
      checkpointer.MarkDirty(Apply(map, *scan, version));
      if (store) {
        ASSERT_TRUE(store->log()
                        .Append(LogRecord::Scan(version, "robot-" + std::to_string(c.robot),
                                                c.index + 1, scan))
                        .ok());
      }
    }
    if (store && checkpoints_after.count(version)) {
      ASSERT_TRUE(checkpointer.Checkpoint(*store, map).ok());
    }
  }
}

class RecoveryTest : public ::testing::TestWithParam<Durability> {};

TEST_P(RecoveryTest, CheckpointPlusReplayedLogEqualsTheUninterruptedMap) {
  MapParams params = SmallParams();
  params.dynamics = Dynamics::kOff;  // see "Lazily recovered" below
  const std::vector<Change> changes = Script(30);
  auto reference = NewMap(params);
  RunChanges(params, changes, *reference, nullptr, {});

  TempDir dir;
  StoreOptions options;
  options.durability = GetParam();
  {
    auto store = std::move(TileStore::Open(dir.path(), options, params)).value();
    auto map = NewMap(params);
    RunChanges(params, changes, *map, store.get(), {8, 16});
    ASSERT_TRUE(MapsIdentical(*reference, *map));
  }  // the map is dropped; only the store remains

  auto store = std::move(TileStore::OpenExisting(dir.path(), options)).value();
  EXPECT_EQ(store->checkpoint_version(), 16u);
  EXPECT_EQ(store->map_version(), changes.size());
  EXPECT_EQ(store->LastSequence("robot-2"), 10u);
  auto recovered = NewMap(params);
  Result<RecoveryReport> report = RecoverMap(*store, *recovered);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->clean());
  EXPECT_EQ(report->checkpoint_version, 16u);
  EXPECT_EQ(report->scans_replayed + report->clears_replayed, changes.size() - 16);
  EXPECT_EQ(report->clears_replayed, 1u);
  EXPECT_EQ(recovered->version(), changes.size());

  // Lazily recovered: only the tiles the log touched are in memory, and each is exact (these
  // scans' free-space rays reach every tile, hence dynamics off in NewMap's params here).
  EXPECT_LT(report->tiles_loaded, store->ListTiles()->size());
  recovered->ForEachTile([&](TileKey k, const Tile& t) {
    const Tile* want = reference->FindTile(k);
    if (want) {
      EXPECT_TRUE(t == *want) << k.x << "," << k.y;
    }
  });
  ASSERT_TRUE(LoadAllTiles(*store, *recovered).ok());
  // Statistics on their own too: a failure says whether the data or only a version stamp is off.
  EXPECT_TRUE(StatisticsIdentical(*reference, *recovered));
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
}

TEST_P(RecoveryTest, LogOnlyAndRepeatedCrashesRecoverExactly) {
  const MapParams params = SmallParams();
  const std::vector<Change> changes = Script(24);
  const std::vector<Change> first(changes.begin(), changes.begin() + 10);
  const std::vector<Change> second(changes.begin() + 10, changes.end());
  auto reference = NewMap(params);
  RunChanges(params, changes, *reference, nullptr, {});

  TempDir dir;
  StoreOptions options;
  options.durability = GetParam();
  {
    auto store = std::move(TileStore::Open(dir.path(), options, params)).value();
    auto map = NewMap(params);
    RunChanges(params, first, *map, store.get(), {});  // no checkpoint at all
  }
  {
    // Restart: recover, then carry on from the recovered version.
    auto store = std::move(TileStore::OpenExisting(dir.path(), options)).value();
    auto map = NewMap(params);
    ASSERT_TRUE(RecoverMap(*store, *map).ok());
    EXPECT_EQ(map->version(), 10u);
    RunChanges(params, second, *map, store.get(), {15});
  }
  auto store = std::move(TileStore::OpenExisting(dir.path(), options)).value();
  auto recovered = NewMap(params);
  ASSERT_TRUE(RecoverMap(*store, *recovered).ok());
  ASSERT_TRUE(LoadAllTiles(*store, *recovered).ok());
  EXPECT_TRUE(StatisticsIdentical(*reference, *recovered));
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
}

INSTANTIATE_TEST_SUITE_P(Durability, RecoveryTest,
                         ::testing::Values(Durability::kSync, Durability::kPeriodic),
                         [](const auto& test) { return std::string(DurabilityName(test.param)); });

// The comparison has teeth: the same scans in another order give other statistics, which is why
// replay must follow version order. Statistics only: MapsIdentical also compares tile versions,
// and those differ between the two orders whatever the statistics are (the control below).
// Mutation checked: RecoverMap (storage/src/recovery.cc) replaying the log's records in reverse
// order makes both RecoveryTest cases fail on StatisticsIdentical.
TEST(RecoveryOrderTest, ScanOrderChangesTheStatistics) {
  const MapParams params = SmallParams();
  auto in_order = NewMap(params), swapped = NewMap(params);
  const auto a = MakeScan(params, 0, 0), b = MakeScan(params, 1, 0);
  ASSERT_FALSE(a->write_tiles.empty());
  Apply(*in_order, *a, 1);
  Apply(*in_order, *b, 2);
  Apply(*swapped, *b, 1);
  Apply(*swapped, *a, 2);
  EXPECT_FALSE(StatisticsIdentical(*in_order, *swapped));

  // Control: the same order at other version numbers has the same statistics, yet MapsIdentical
  // tells the maps apart by their tile versions alone.
  auto renumbered = NewMap(params);
  Apply(*renumbered, *a, 5);
  Apply(*renumbered, *b, 6);
  renumbered->set_version(2);
  EXPECT_TRUE(StatisticsIdentical(*in_order, *renumbered));
  EXPECT_FALSE(MapsIdentical(*in_order, *renumbered));
}

}  // namespace
}  // namespace bgkmap::storage
