// Residency of the served map's tiles: eviction drops only clean, unpinned tiles, least recently
// used first; evicted tiles load back bitwise; a corrupt stored tile is DataLoss for readers and
// left out for changes; the corrupt-tile rule holds even for a tile a scan rebuilt in memory.
#include "serving/tile_residency.h"

#include <gtest/gtest.h>

#include <cstring>

#include "serving_test_util.h"

namespace bgkmap {
namespace {

using testing::FakeDurability;
using testing::GroundScan;
using testing::SameStatistics;
using testing::ServedMapFixture;

class ResidencyTest : public ServedMapFixture {};

// Mutation checked: evicting tiles with version > durable_version() fails this test (the region
// answered after eviction would lose the last scan).
TEST_F(ResidencyTest, EvictsOnlyCleanTilesAndLoadsThemBackExactly) {
  ASSERT_TRUE(Scan(1, 0, 0).status.ok());
  ASSERT_TRUE(Scan(2, 20, 0).status.ok());
  const CellBox box{{-100, -100}, {300, 100}};
  const std::vector<Layer> layers = {Layer::kElevation, Layer::kTraversability};
  Result<Raster> before = map_.ReadRegion(box, layers, 1);
  ASSERT_TRUE(before.ok());
  const uint64_t resident = map_.Residency().resident_tiles;
  ASSERT_GT(resident, 0u);

  // Nothing is durable yet: nothing may go.
  map_.Evict(0);
  EXPECT_EQ(map_.Residency().resident_tiles, resident);
  EXPECT_EQ(map_.Residency().tiles_evicted, 0u);

  ASSERT_TRUE(map_.Checkpoint().ok());
  map_.Evict(0);
  EXPECT_EQ(map_.Residency().resident_tiles, 0u);
  EXPECT_EQ(map_.Residency().tiles_evicted, resident);

  // A third scan changes some tiles; they stay when the map is evicted again.
  ASSERT_TRUE(Scan(3, 0, 0, -0.5f).status.ok());
  const uint64_t changed = map_.Residency().resident_tiles;
  ASSERT_GT(changed, 0u);
  map_.Evict(0);
  EXPECT_EQ(map_.Residency().resident_tiles, changed);

  ASSERT_TRUE(map_.Checkpoint().ok());
  map_.Evict(0);
  Result<Raster> after = map_.ReadRegion(box, layers, 1);
  ASSERT_TRUE(after.ok());
  EXPECT_GT(map_.Residency().tiles_loaded, 0u);
  // The region now holds scan 3 too: compare with the same scans in one offline map.
  std::unique_ptr<TerrainMap> offline = TerrainMap::Create(map_.params()).value();
  for (auto [z, cx] : {std::pair{-1.0f, 0.0f}, {-1.0f, 20.0f}, {-0.5f, 0.0f}}) {
    std::shared_ptr<const PreparedScan> s = GroundScan(map_.params(), cx, 0, z);
    offline->Integrate(*s, offline->MakeWindow(*s), 1);
  }
  EXPECT_TRUE(SameStatistics(*map_.Snapshot(), *offline));
  const Raster expected = ExtractRaster(*offline, box, layers, 1);
  ASSERT_EQ(after->data.size(), expected.data.size());
  for (size_t i = 0; i < expected.data.size(); ++i) {
    ASSERT_EQ(after->data[i].size(), expected.data[i].size());
    EXPECT_EQ(0, std::memcmp(after->data[i].data(), expected.data[i].data(),
                             expected.data[i].size() * sizeof(float)));
  }
}

// Pins and recency, on a residency of its own over the fake store.
TEST(TileResidencyTest, PinnedTilesStayAndTheLeastRecentlyUsedGoFirst) {
  MapParams params;
  FakeDurability store(params);
  TileTable table(TerrainMap::Create(params).value(), /*keep_cleared=*/true);
  TileResidency residency(table, store, /*persists=*/true, 0, {});
  // Four stored tiles, loaded by pins in the order a, b, c, d.
  std::vector<TileKey> keys = {{0, 0}, {1, 0}, {2, 0}, {3, 0}};
  std::vector<std::unique_ptr<Tile>> tiles;
  for (size_t i = 0; i < keys.size(); ++i) {
    tiles.push_back(std::make_unique<Tile>(params.tile_size));
    tiles.back()->w()[0] = 1.0 + i;
    tiles.back()->set_version(1);
  }
  ASSERT_TRUE(store.WriteCheckpoint(1, keys, tiles).ok());
  {
    for (TileKey k : keys) ASSERT_TRUE(residency.Pin({k}, true).ok());
  }
  EXPECT_EQ(residency.Stats().tiles_loaded, 4u);
  Result<TileResidency::Pins> held = residency.Pin({keys[0]}, true);  // a: pinned, most recent
  ASSERT_TRUE(held.ok());
  // Room for two tiles: b and c (least recently used, unpinned) go; a (pinned) and d stay.
  residency.Evict(2 * table.TileBytes());
  EXPECT_EQ(table.NotResident(keys), (std::vector<TileKey>{keys[1], keys[2]}));
  residency.Evict(0);
  EXPECT_EQ(table.NotResident(keys), (std::vector<TileKey>{keys[1], keys[2], keys[3]}));
  held->Release();
  residency.Evict(0);
  EXPECT_EQ(table.NotResident(keys).size(), 4u);
  EXPECT_EQ(residency.Stats().tiles_evicted, 4u);
}

TEST(TileResidencyTest, CorruptStoredTileIsDataLossForReadersAndLeftOutForChanges) {
  MapParams params;
  FakeDurability store(params);
  TileTable table(TerrainMap::Create(params).value(), /*keep_cleared=*/true);
  TileResidency residency(table, store, /*persists=*/true, 0, {});
  std::vector<TileKey> keys = {{5, 5}};
  std::vector<std::unique_ptr<Tile>> tiles;
  tiles.push_back(std::make_unique<Tile>(params.tile_size));
  tiles.back()->w()[0] = 1.0;
  ASSERT_TRUE(store.WriteCheckpoint(1, keys, tiles).ok());
  store.corrupt.insert(keys[0]);
  Result<TileResidency::Pins> reader = residency.Pin(keys, /*strict=*/true);
  EXPECT_EQ(reader.status().code(), Status::Code::kDataLoss);
  EXPECT_TRUE(residency.Pin(keys, /*strict=*/false).ok());
  EXPECT_EQ(table.NotResident(keys).size(), 1u);  // left out: a change starts it afresh
}

// Mutation checked: removing RefuseCorrupt() from ServedMap::ReadCells/ReadRegion/ReadTile fails
// this test: the tile a later scan rebuilt in memory would be answered.
TEST_F(ResidencyTest, TileTheStoreFoundCorruptIsNeverAnsweredEvenOnceRebuilt) {
  ASSERT_TRUE(Scan(1).status.ok());
  const TileKey k = map_.geometry().TileOf(map_.geometry().CellAt(3.0, 0.0));
  {
    std::lock_guard lock(durability_.mu());
    durability_.corrupt.insert(k);
  }
  ASSERT_TRUE(Scan(2, 0, 0, -0.9f).status.ok());  // the tile is in memory, rebuilt
  const CellIndex cell = map_.geometry().CellAt(3.0, 0.0);
  const CellIndex cells[] = {cell};
  const std::string name = "tile (" + std::to_string(k.x) + ", " + std::to_string(k.y) + ")";
  Result<std::vector<CellEstimate>> points = map_.ReadCells(cells);
  EXPECT_EQ(points.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(points.status().message().find(name), std::string::npos) << points.status().message();
  Result<Raster> region = map_.ReadRegion({cell, cell}, {Layer::kElevation}, 1);
  EXPECT_EQ(region.status().code(), Status::Code::kDataLoss);
  Result<TileContent> tile = map_.ReadTile(k, {Layer::kElevation});
  EXPECT_EQ(tile.status().code(), Status::Code::kDataLoss);
  // Its neighbours still answer.
  const CellIndex far[] = {map_.geometry().CellAt(-3.0, 0.0)};
  ASSERT_NE(map_.geometry().TileOf(far[0]), k);
  EXPECT_TRUE(map_.ReadCells(far).ok());
}

}  // namespace
}  // namespace bgkmap
