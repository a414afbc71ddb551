// The incremental map summary equals a count over every tile after scans, clears, imports and
// an undone import, and its bounds shrink when a clear removes the map's edge.
#include "serving/map_summary.h"

#include <gtest/gtest.h>

#include "serving_test_util.h"

namespace bgkmap {
namespace {

using testing::ServedMapFixture;

// Independent of MapSummaryIndex: walks every cell of a copy of the map.
MapSummary BruteForce(const TerrainMap& map) {
  MapSummary s;
  map.ForEachTile([&](TileKey k, const Tile& t) {
    bool any = false;
    const CellIndex o = map.geometry().TileOrigin(k);
    for (int i = 0; i < t.cell_count(); ++i) {
      if (!t.IsKnown(i)) continue;
      any = true;
      ++s.known_cells;
      s.known_bounds.Extend({o.x + i % t.tile_size(), o.y + i / t.tile_size()});
    }
    s.tile_count += any;
  });
  return s;
}

void ExpectSummary(const MapSummary& got, const MapSummary& want) {
  EXPECT_EQ(got.tile_count, want.tile_count);
  EXPECT_EQ(got.known_cells, want.known_cells);
  EXPECT_EQ(got.known_bounds, want.known_bounds);
}

class MapSummaryTest : public ServedMapFixture {};

// Mutation checked: not recomputing the bounds after a shrink (MapSummaryIndex::Update) fails
// the clear step below; so does a scan that does not mark its tiles stale (RunScan).
TEST_F(MapSummaryTest, FollowsScansClearsAndImportsExactly) {
  ExpectSummary(map_.Summary(), {});
  ASSERT_TRUE(Scan(1, 0, 0).status.ok());
  ASSERT_TRUE(Scan(2, 30, 10).status.ok());
  ASSERT_TRUE(Scan(3, 2, 1, -0.8f).status.ok());
  ExpectSummary(map_.Summary(), BruteForce(*map_.Snapshot()));

  // Clear the eastern scan entirely: the bounds must shrink back to the western ones.
  const ClearOutcome cleared = Clear(CellBox{{200, -100}, {400, 300}});
  ASSERT_TRUE(cleared.status.ok());
  ASSERT_FALSE(cleared.changed_tiles.empty());
  const MapSummary after_clear = BruteForce(*map_.Snapshot());
  ExpectSummary(map_.Summary(), after_clear);
  EXPECT_LT(after_clear.known_bounds.max.x, 200);

  // A partial clear through the middle.
  ASSERT_TRUE(Clear(CellBox{{-5, -100}, {5, 100}}).status.ok());
  ExpectSummary(map_.Summary(), BruteForce(*map_.Snapshot()));

  // An import far away, then one whose checkpoint fails (undone).
  std::unique_ptr<TerrainMap> other = TerrainMap::Create(map_.params()).value();
  std::shared_ptr<const PreparedScan> s = testing::GroundScan(map_.params(), -50, -50);
  other->Integrate(*s, other->MakeWindow(*s), 1);
  std::vector<TileKey> keys;
  other->ForEachTile([&](TileKey k, const Tile&) { keys.push_back(k); });
  std::sort(keys.begin(), keys.end());
  std::vector<std::unique_ptr<Tile>> tiles;
  for (TileKey k : keys) tiles.push_back(std::make_unique<Tile>(*other->FindTile(k)));
  ASSERT_TRUE(Import(keys, tiles).status.ok());
  ExpectSummary(map_.Summary(), BruteForce(*map_.Snapshot()));
  const MapSummary before_failed = map_.Summary();
  durability_.fail_write = true;
  ASSERT_FALSE(Import(keys, tiles).status.ok());
  ExpectSummary(map_.Summary(), before_failed);
  ExpectSummary(map_.Summary(), BruteForce(*map_.Snapshot()));
}

// Tiles evicted to the store still count: the summary never reads tiles.
TEST_F(MapSummaryTest, CountsTilesThatAreOnlyInTheStore) {
  ASSERT_TRUE(Scan(1).status.ok());
  const MapSummary before = map_.Summary();
  ASSERT_TRUE(map_.Checkpoint().ok());
  map_.Evict(0);
  ASSERT_EQ(map_.Residency().resident_tiles, 0u);
  ExpectSummary(map_.Summary(), before);
}

TEST(MapSummaryIndexTest, BoundsShrinkOnlyWhenAnEdgeTileShrinks) {
  MapSummaryIndex index;
  const MapSummaryIndex::Recount none = [](std::span<const TileKey> keys) {
    EXPECT_TRUE(keys.empty());
    return std::vector<TileSummary>(keys.size());
  };
  const TileKey a{0, 0}, b{1, 0};
  const TileSummary sa{4, {{0, 0}, {1, 1}}}, sb{2, {{70, 0}, {71, 0}}};
  const TileKey keys[] = {a, b};
  const TileSummary both[] = {sa, sb};
  index.Update(keys, both);
  EXPECT_EQ(index.Get(none).known_cells, 6u);
  EXPECT_EQ(index.Get(none).known_bounds, (CellBox{{0, 0}, {71, 1}}));
  const TileSummary gone[] = {TileSummary{}};
  index.Update(std::span<const TileKey>(&b, 1), gone);
  EXPECT_EQ(index.Get(none).tile_count, 1u);
  EXPECT_EQ(index.Get(none).known_cells, 4u);
  EXPECT_EQ(index.Get(none).known_bounds, (CellBox{{0, 0}, {1, 1}}));
}

}  // namespace
}  // namespace bgkmap

namespace bgkmap {
namespace {

// A tile marked stale is recounted at the next read, and only then.
TEST(MapSummaryIndexTest, RecountsOnlyStaleTilesAndOnlyWhenRead) {
  MapSummaryIndex index;
  std::vector<TileKey> asked;
  const TileSummary s{3, {{0, 0}, {2, 0}}};
  const MapSummaryIndex::Recount recount = [&](std::span<const TileKey> keys) {
    asked.insert(asked.end(), keys.begin(), keys.end());
    return std::vector<TileSummary>(keys.size(), s);
  };
  const TileKey a{0, 0}, b{4, 4};
  index.MarkStale(std::span<const TileKey>(&a, 1));
  index.MarkStale(std::span<const TileKey>(&a, 1));
  index.MarkStale(std::span<const TileKey>(&b, 1));
  EXPECT_TRUE(asked.empty());
  EXPECT_EQ(index.Get(recount).known_cells, 6u);
  EXPECT_EQ(asked, (std::vector<TileKey>{a, b}));
  EXPECT_EQ(index.Get(recount).tile_count, 2u);
  EXPECT_EQ(asked.size(), 2u);  // nothing stale: nothing recounted
}

}  // namespace
}  // namespace bgkmap
