// Residency of the served map's tiles: eviction drops only clean, unpinned tiles, least recently
// used first; evicted tiles load back bitwise; a corrupt stored tile is DataLoss for readers and
// left out for changes; the corrupt-tile rule holds even for a tile a scan rebuilt in memory.
#include "serving/tile_residency.h"

#include <gtest/gtest.h>

#include <cstring>
#include <optional>

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

// Every field of every estimate, bit for bit (NaN for unknown included).
bool SameEstimates(const std::vector<CellEstimate>& a, const std::vector<CellEstimate>& b) {
  if (a.size() != b.size()) return false;
  auto same = [](float x, float y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  for (size_t i = 0; i < a.size(); ++i) {
    if (!same(a[i].elevation, b[i].elevation) ||
        !same(a[i].elevation_variance, b[i].elevation_variance) ||
        !same(a[i].traversability, b[i].traversability) ||
        !same(a[i].traversability_variance, b[i].traversability_variance) ||
        a[i].state != b[i].state || !same(a[i].elevation_weight, b[i].elevation_weight) ||
        !same(a[i].disagreement, b[i].disagreement) || a[i].block_reasons != b[i].block_reasons) {
      return false;
    }
  }
  return true;
}

// The points read at once are those ReadCells() reads, bit for bit; a tile evicted to the store
// is left to ReadCells() (which loads it), then read at once again.
TEST_F(ResidencyTest, PointsReadAtOnceAreThoseReadCellsReadsAndEvictedTilesWait) {
  ASSERT_TRUE(Scan(1, 0, 0).status.ok());
  std::vector<CellIndex> cells;
  for (double x = -20; x <= 20; x += 0.7) cells.push_back(map_.geometry().CellAt(x, 0.3 * x));
  Result<std::vector<CellEstimate>> waited = map_.ReadCells(cells);
  ASSERT_TRUE(waited.ok());
  std::optional<Result<std::vector<CellEstimate>>> now = map_.TryReadCellsNow(cells);
  ASSERT_TRUE(now.has_value());
  ASSERT_TRUE(now->ok());
  EXPECT_TRUE(SameEstimates(**now, *waited));

  ASSERT_TRUE(map_.Checkpoint().ok());
  map_.Evict(0);
  ASSERT_EQ(map_.Residency().resident_tiles, 0u);
  EXPECT_FALSE(map_.TryReadCellsNow(cells).has_value());
  EXPECT_EQ(map_.Residency().tiles_loaded, 0u);
  ASSERT_TRUE(map_.ReadCells(cells).ok());
  EXPECT_GT(map_.Residency().tiles_loaded, 0u);
  now = map_.TryReadCellsNow(cells);
  ASSERT_TRUE(now.has_value() && now->ok());
  EXPECT_TRUE(SameEstimates(**now, *waited));
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

// What a point query answered on the receiving thread may pin: only tiles it can read at once,
// packed or dense, never one it would have to load.
TEST(TileResidencyTest, TryPinInMemoryNeverLoads) {
  MapParams params;
  FakeDurability store(params);
  TileTable table(TerrainMap::Create(params).value(), /*keep_cleared=*/true);
  TileResidency residency(table, store, /*persists=*/true, 0, {}, /*dense_limit_bytes=*/1);
  const TileKey stored{0, 0}, absent{7, 7};
  std::vector<std::unique_ptr<Tile>> tiles;
  tiles.push_back(std::make_unique<Tile>(params.tile_size));
  tiles.back()->w()[3] = 2.0;
  ASSERT_TRUE(store.WriteCheckpoint(1, std::vector<TileKey>{stored}, tiles).ok());

  EXPECT_FALSE(residency.TryPinInMemory({stored}).has_value());  // it would load it
  EXPECT_EQ(residency.Stats().tiles_loaded, 0u);
  EXPECT_TRUE(residency.TryPinInMemory({absent}).has_value());  // nothing to read: unknown
  ASSERT_TRUE(residency.Pin({stored}, true).ok());              // loaded (and released)
  EXPECT_TRUE(residency.TryPinInMemory({stored, absent}).has_value());
  table.Pack(std::vector<TileKey>{stored});
  ASSERT_EQ(table.packed_tiles(), 1u);
  EXPECT_TRUE(residency.TryPinInMemory({stored}).has_value());
  EXPECT_EQ(table.packed_tiles(), 1u);  // read as it is
  table.Erase(std::vector<TileKey>{stored});  // evicted
  EXPECT_FALSE(residency.TryPinInMemory({stored}).has_value());
  EXPECT_EQ(residency.Stats().tiles_loaded, 1u);
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
  std::optional<Result<std::vector<CellEstimate>>> at_once = map_.TryReadCellsNow(cells);
  ASSERT_TRUE(at_once.has_value());
  EXPECT_EQ(at_once->status().code(), Status::Code::kDataLoss);
  // Its neighbours still answer.
  const CellIndex far[] = {map_.geometry().CellAt(-3.0, 0.0)};
  ASSERT_NE(map_.geometry().TileOf(far[0]), k);
  EXPECT_TRUE(map_.ReadCells(far).ok());
}

}  // namespace
}  // namespace bgkmap
