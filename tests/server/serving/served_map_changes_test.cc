// ServedMap's change transactions without gRPC or RocksDB: a change the journal refuses is not
// applied and does not block later ones; an import whose checkpoint fails is undone; a failed
// checkpoint write resumes the store at the next barrier; barriers take no version.
#include <gtest/gtest.h>

#include <algorithm>

#include "serving_test_util.h"

namespace bgkmap {
namespace {

using testing::FakeDurability;
using testing::SameStatistics;
using testing::ServedMapFixture;

class ServedMapChangesTest : public ServedMapFixture {};

// Mutation checked: applying the scan although Record() failed (RunScan) fails this test.
TEST_F(ServedMapChangesTest, RefusedScanIsNotAppliedAndItsRetryIsAccepted) {
  ASSERT_TRUE(Scan(1).status.ok());
  const uint64_t cells = map_.Summary().known_cells;
  ASSERT_GT(cells, 0u);

  durability_.fail_record = true;
  const ScanOutcome refused = Scan(2, 1.0f, 0.0f);
  EXPECT_FALSE(refused.status.ok());
  EXPECT_EQ(refused.version, 2u);
  map_.WaitIdle();
  EXPECT_EQ(map_.robots().LastSequence("r"), 1u);  // a retry is not a duplicate
  EXPECT_EQ(map_.scans_applied(), 1u);
  EXPECT_EQ(map_.applied_version(), 2u);  // finished: later changes are not blocked
  EXPECT_EQ(map_.Summary().known_cells, cells);
  std::unique_ptr<TerrainMap> snapshot = map_.Snapshot();
  ASSERT_GT(snapshot->tile_count(), 0u);
  snapshot->ForEachTile([](TileKey, const Tile& t) { EXPECT_LE(t.version(), 1u); });

  durability_.fail_record = false;
  const ScanOutcome retry = Scan(2, 1.0f, 0.0f);
  EXPECT_TRUE(retry.status.ok());
  EXPECT_EQ(retry.version, 3u);
  EXPECT_EQ(durability_.recorded, (std::vector<uint64_t>{1, 3}));
  EXPECT_EQ(map_.robots().LastSequence("r"), 2u);
  EXPECT_GT(map_.Summary().known_cells, cells);
}

TEST_F(ServedMapChangesTest, RefusedClearClearsNothing) {
  ASSERT_TRUE(Scan(1).status.ok());
  const std::unique_ptr<TerrainMap> before = map_.Snapshot();
  durability_.fail_record = true;
  const ClearOutcome refused = Clear(CellBox{{-100, -100}, {100, 100}});
  EXPECT_FALSE(refused.status.ok());
  EXPECT_TRUE(refused.changed_tiles.empty());
  EXPECT_TRUE(SameStatistics(*map_.Snapshot(), *before));
  EXPECT_EQ(map_.Summary().known_cells, static_cast<uint64_t>(before->CountKnownCells()));
}

// A barrier (Checkpoint) runs after every earlier change, sees them all marked, and takes no
// version of its own.
TEST_F(ServedMapChangesTest, CheckpointCoversEveryEarlierChangeAndTakesNoVersion) {
  for (uint64_t s = 1; s <= 3; ++s) {
    map_.SubmitScan({"r", s, {}, {}}, testing::GroundScan(map_.params(), s * 3.0f, 0), [](auto) {});
  }
  ASSERT_TRUE(map_.Checkpoint().ok());
  ASSERT_EQ(durability_.checkpoints.size(), 1u);
  EXPECT_EQ(durability_.checkpoints[0].version, 3u);
  EXPECT_FALSE(durability_.checkpoints[0].keys.empty());
  EXPECT_EQ(map_.checkpointer().dirty_tiles(), 0u);
  map_.WaitIdle();
  EXPECT_EQ(map_.applied_version(), 3u);
  EXPECT_EQ(Scan(4).version, 4u);  // the barrier took no version
}

// Mutation checked: dropping the ReplaceTiles() undo in RunImport fails this test.
TEST_F(ServedMapChangesTest, ImportWhoseCheckpointFailsIsUndone) {
  ASSERT_TRUE(Scan(1).status.ok());
  const std::unique_ptr<TerrainMap> before = map_.Snapshot();
  const MapSummary summary_before = map_.Summary();
  // Import the map onto itself: every statistic would double.
  std::vector<TileKey> keys;
  before->ForEachTile([&](TileKey k, const Tile&) { keys.push_back(k); });
  std::sort(keys.begin(), keys.end());
  ASSERT_FALSE(keys.empty());
  std::vector<std::unique_ptr<Tile>> tiles;
  for (TileKey k : keys) tiles.push_back(std::make_unique<Tile>(*before->FindTile(k)));

  durability_.fail_write = true;
  const ImportOutcome failed = Import(keys, tiles);
  EXPECT_EQ(failed.status.code(), Status::Code::kIoError) << failed.status.ToString();
  EXPECT_TRUE(SameStatistics(*map_.Snapshot(), *before));
  EXPECT_EQ(map_.Summary().known_cells, summary_before.known_cells);

  // The store resumes at the next barrier; the same import then goes through.
  durability_.fail_write = false;
  const ImportOutcome ok = Import(keys, tiles);
  ASSERT_TRUE(ok.status.ok()) << ok.status.ToString();
  EXPECT_GE(durability_.resumes, 1);
  EXPECT_EQ(durability_.checkpoints.back().version, ok.version);
  const std::unique_ptr<TerrainMap> after = map_.Snapshot();
  for (TileKey k : keys) {
    EXPECT_EQ(after->FindTile(k)->w()[0], 2 * before->FindTile(k)->w()[0]);
  }
}

// Mutation checked: skipping Resume() in Checkpointer::Capture fails this test.
TEST_F(ServedMapChangesTest, FailedCheckpointResumesTheStoreAtTheNextBarrier) {
  ASSERT_TRUE(Scan(1).status.ok());
  durability_.fail_write = true;
  EXPECT_FALSE(map_.Checkpoint().ok());
  EXPECT_TRUE(durability_.write_failed());
  EXPECT_GT(map_.checkpointer().dirty_tiles(), 0u);  // kept for the next checkpoint
  durability_.fail_write = false;
  ASSERT_TRUE(map_.Checkpoint().ok());
  EXPECT_EQ(durability_.resumes, 1);
  EXPECT_FALSE(durability_.write_failed());
  EXPECT_EQ(map_.checkpointer().dirty_tiles(), 0u);
  ASSERT_EQ(durability_.checkpoints.size(), 1u);
  EXPECT_FALSE(durability_.checkpoints[0].keys.empty());
}

TEST_F(ServedMapChangesTest, DuplicateAndTooManyRobotsAreRefusedAtAdmission) {
  ASSERT_TRUE(Scan(5).status.ok());
  EXPECT_EQ(
      map_.SubmitScan({"r", 5, {}, {}}, testing::GroundScan(map_.params(), 0, 0), [](auto) {}),
      ServedMap::Admission::kDuplicate);
  for (int i = 0; i < 15; ++i) {
    EXPECT_EQ(map_.SubmitScan({"robot" + std::to_string(i), 1, {}, {}},
                              testing::GroundScan(map_.params(), 0, 0), [](auto) {}),
              ServedMap::Admission::kAdmitted);
  }
  EXPECT_EQ(map_.SubmitScan({"one-too-many", 1, {}, {}}, testing::GroundScan(map_.params(), 0, 0),
                            [](auto) {}),
            ServedMap::Admission::kTooManyRobots);
  map_.WaitIdle();
  EXPECT_EQ(map_.scans_applied(), 16u);
}

// Issue 12: one scan with sequence 2^64-1 must not make every later scan of the robot a
// duplicate; a retired robot starts afresh and frees its slot.
TEST(RobotRegistryTest, JumpsAreRefusedAndRetiredRobotsStartAfresh) {
  RobotRegistry robots(/*max_robots=*/2, /*max_sequence_jump=*/1000);
  uint64_t previous = 0;
  EXPECT_EQ(robots.Admit("a", 5, {}, 1, &previous), RobotRegistry::Admission::kAdmitted);
  EXPECT_EQ(robots.Admit("a", UINT64_MAX, {}, 1, &previous),
            RobotRegistry::Admission::kSequenceJump);
  EXPECT_EQ(previous, 5u);
  EXPECT_EQ(robots.Admit("a", 1005, {}, 1, &previous), RobotRegistry::Admission::kAdmitted);
  EXPECT_EQ(robots.Admit("a", 3, {}, 1, &previous), RobotRegistry::Admission::kDuplicate);
  EXPECT_EQ(previous, 1005u);
  EXPECT_EQ(robots.Admit("new", 1001, {}, 1, &previous), RobotRegistry::Admission::kSequenceJump);
  EXPECT_EQ(robots.Admit("b", 1, {}, 1, &previous), RobotRegistry::Admission::kAdmitted);
  EXPECT_EQ(robots.Admit("c", 1, {}, 1, &previous), RobotRegistry::Admission::kTooManyRobots);
  const std::optional<RobotStats> gone = robots.Retire("a");
  ASSERT_TRUE(gone.has_value());
  EXPECT_EQ(gone->last_sequence, 1005u);
  EXPECT_FALSE(robots.Retire("a").has_value());
  EXPECT_EQ(robots.Admit("c", 1, {}, 1, &previous), RobotRegistry::Admission::kAdmitted);
  EXPECT_EQ(robots.Admit("a", 1, {}, 1, &previous), RobotRegistry::Admission::kTooManyRobots);
}

}  // namespace
}  // namespace bgkmap
