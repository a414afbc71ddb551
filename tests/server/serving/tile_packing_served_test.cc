// Packing under storage.dense_tiles_mb (serving/tile_residency.h): a served map whose tiles are
// packed whenever they are not in use answers regions, points, summaries and snapshots bit for
// bit as the same map kept dense, after scans, a clear, an import and an eviction round trip,
// while its tiles take fewer bytes.
#include <gtest/gtest.h>

#include <cstring>
#include <future>
#include <limits>

#include "serving/tile_residency.h"
#include "serving_test_util.h"

namespace bgkmap {
namespace {

using testing::FakeDurability;
using testing::GroundScan;
using testing::SameStatistics;

// One served map on the fake store; `dense_limit` as storage.dense_tiles_mb in bytes.
struct Served {
  explicit Served(uint64_t dense_limit)
      : durability(MapParams{}),
        map(TerrainMap::Create(MapParams{}).value(), durability, pool, Options(dense_limit)) {}
  static ServedMapOptions Options(uint64_t dense_limit) {
    ServedMapOptions o;
    o.max_robots = 16;
    o.dense_tile_limit_bytes = dense_limit;
    o.pack_after_idle = std::chrono::milliseconds(0);  // pack right after use
    return o;
  }
  void Scan(uint64_t sequence, float cx, float cy, float z) {
    std::promise<ScanOutcome> done;
    ASSERT_EQ(map.SubmitScan({"r", sequence, {}, {}}, GroundScan(map.params(), cx, cy, z),
                             [&done](ScanOutcome o) { done.set_value(std::move(o)); }),
              ServedMap::Admission::kAdmitted);
    ASSERT_TRUE(done.get_future().get().status.ok());
  }
  void Clear(const CellBox& box) {
    std::promise<ClearOutcome> done;
    map.SubmitClear(box, [&done](const ClearOutcome& o) { done.set_value(o); });
    ASSERT_TRUE(done.get_future().get().status.ok());
  }
  void Import(const std::vector<TileKey>& keys, const std::vector<std::unique_ptr<Tile>>& tiles) {
    std::promise<ImportOutcome> done;
    map.SubmitImport(keys, tiles, [&done](const ImportOutcome& o) { done.set_value(o); });
    ASSERT_TRUE(done.get_future().get().status.ok());
  }
  // Packs every tile not in use (the budget is below one tile), evicts nothing.
  void PackAll() { map.Evict(std::numeric_limits<uint64_t>::max()); }

  boost::asio::thread_pool pool{2};
  FakeDurability durability;
  ServedMap map;
};

void ExpectSameAnswers(Served& packed, Served& dense) {
  packed.PackAll();  // the snapshot copies packed tiles; the reads unpack what they pin
  const CellBox box{{-150, -150}, {450, 150}};
  std::vector<Layer> layers;
  for (int l = 0; l < kLayerCount; ++l) layers.push_back(static_cast<Layer>(l));
  EXPECT_EQ(packed.map.Summary().known_cells, dense.map.Summary().known_cells);
  EXPECT_TRUE(SameStatistics(*packed.map.Snapshot(), *dense.map.Snapshot()));
  for (int stride : {1, 3}) {
    Result<Raster> a = packed.map.ReadRegion(box, layers, stride);
    Result<Raster> b = dense.map.ReadRegion(box, layers, stride);
    ASSERT_TRUE(a.ok() && b.ok());
    ASSERT_EQ(a->data.size(), b->data.size());
    for (size_t i = 0; i < a->data.size(); ++i) {
      ASSERT_EQ(a->data[i].size(), b->data[i].size());
      EXPECT_EQ(
          0, std::memcmp(a->data[i].data(), b->data[i].data(), a->data[i].size() * sizeof(float)))
          << "layer " << i << " stride " << stride;
    }
  }
  packed.PackAll();
  std::vector<CellIndex> cells;
  for (int x = -120; x <= 420; x += 7) cells.push_back({x, x % 50});
  Result<std::vector<CellEstimate>> pa = packed.map.ReadCells(cells);
  Result<std::vector<CellEstimate>> pb = dense.map.ReadCells(cells);
  ASSERT_TRUE(pa.ok() && pb.ok());
  for (size_t i = 0; i < cells.size(); ++i) {
    for (Layer l : layers) {
      const float a = (*pa)[i].Get(l), b = (*pb)[i].Get(l);
      EXPECT_EQ(0, std::memcmp(&a, &b, sizeof(float))) << "cell " << i;
    }
  }
}

// Mutation checked: packing with a cell kept iff its W is nonzero (not any bit) loses the
// imported traversability-only cell and fails this test.
TEST(TilePackingServedTest, PackedMapAnswersAsTheDenseOneAndTakesLessMemory) {
  Served packed(/*dense_limit=*/1), dense(/*dense_limit=*/0);
  uint64_t seq = 0;
  for (auto [cx, z] : {std::pair{0.0f, -1.0f}, {20.0f, -1.0f}, {0.0f, -0.5f}, {30.0f, -0.8f}}) {
    ++seq;
    packed.Scan(seq, cx, 0, z);
    dense.Scan(seq, cx, 0, z);
    packed.PackAll();  // the next scan unpacks what it touches
  }
  packed.PackAll();
  const ResidencyStats p = packed.map.Residency(), d = dense.map.Residency();
  EXPECT_EQ(p.resident_tiles, d.resident_tiles);
  EXPECT_EQ(p.packed_tiles, p.resident_tiles);
  EXPECT_EQ(d.packed_tiles, 0u);
  EXPECT_LT(p.resident_bytes * 2, d.resident_bytes);  // ground disks: tiles mostly empty
  ExpectSameAnswers(packed, dense);

  // A clear through packed tiles, then an import onto them.
  packed.PackAll();
  packed.Clear({{-10, -10}, {40, 25}});
  dense.Clear({{-10, -10}, {40, 25}});
  ExpectSameAnswers(packed, dense);
  packed.PackAll();
  const TileKey key = packed.map.geometry().TileOf({0, 0});
  std::vector<std::unique_ptr<Tile>> tiles;
  tiles.push_back(std::make_unique<Tile>(packed.map.params().tile_size));
  tiles.back()->w()[5] = 2.0;
  tiles.back()->s()[5] = -3.0;
  tiles.back()->a()[7] = 0.5f;  // known by traversability alone: W stays 0
  packed.Import({key}, tiles);
  dense.Import({key}, tiles);
  ExpectSameAnswers(packed, dense);

  // Checkpointed packed, evicted, loaded back.
  packed.PackAll();
  ASSERT_TRUE(packed.map.Checkpoint().ok());
  packed.map.Evict(0);
  EXPECT_EQ(packed.map.Residency().resident_tiles, 0u);
  // (Read back first: the fake store's Snapshot() cannot load tiles itself.)
  ASSERT_TRUE(packed.map.ReadRegion({{-150, -150}, {450, 150}}, {Layer::kElevation}, 1).ok());
  ExpectSameAnswers(packed, dense);
}

// Pins: a tile in use is never packed; it is dense while pinned and packed after.
TEST(TilePackingServedTest, PinnedTilesStayDense) {
  MapParams params;
  FakeDurability store(params);
  TileTable table(TerrainMap::Create(params).value(), /*keep_cleared=*/true);
  TileResidency residency(table, store, /*persists=*/true, 0, {}, /*dense_limit_bytes=*/1,
                          std::chrono::milliseconds(0));
  const std::vector<TileKey> keys = {{0, 0}, {1, 0}};
  std::vector<std::unique_ptr<Tile>> tiles;
  for (size_t i = 0; i < keys.size(); ++i) {
    tiles.push_back(std::make_unique<Tile>(params.tile_size));
    tiles.back()->w()[i] = 1.0;
  }
  table.ReplaceTiles(keys, tiles);
  Result<TileResidency::Pins> held = residency.Pin({keys[0]}, true);
  ASSERT_TRUE(held.ok());
  residency.Evict(std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(residency.Stats().packed_tiles, 1u);  // keys[1] only
  held->Release();
  residency.Evict(std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(residency.Stats().packed_tiles, 2u);
  EXPECT_LT(residency.Stats().resident_bytes, table.TileBytes());
  ASSERT_TRUE(residency.Pin({keys[1]}, true).ok());  // unpacked while pinned, and stays so
  EXPECT_EQ(residency.Stats().packed_tiles, 1u);
  EXPECT_EQ(table.DenseBytes(), table.TileBytes());
}

}  // namespace
}  // namespace bgkmap
