// TileStore::NewSnapshot(): a view of the stored tiles as of one moment. Checkpoints taken after
// it (tiles rewritten, deleted, added) change the store, not the view.
#include "bgkmap/storage/tile_snapshot.h"

#include <gtest/gtest.h>

#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::Checkpointer;
using testing::MakeScan;
using testing::NewMap;
using testing::SmallParams;
using testing::TempDir;

std::vector<TileKey> Keys(const std::vector<StoredTileInfo>& tiles) {
  std::vector<TileKey> keys;
  for (const StoredTileInfo& t : tiles) keys.push_back(t.key);
  return keys;
}

TEST(TileSnapshotTest, LaterCheckpointsDoNotChangeTheSnapshot) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), {}, params)).value();
  auto map = NewMap(params);
  Checkpointer checkpointer;
  for (int v = 1; v <= 6; ++v) checkpointer.MarkDirty(Apply(*map, *MakeScan(params, 0, v), v));
  ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
  const std::unique_ptr<TerrainMap> at_six = NewMap(params);
  map->ForEachTile([&](TileKey k, const Tile& t) { at_six->AddTile(k, t); });
  const std::vector<TileKey> keys_at_six = Keys(*store->ListTiles());

  std::unique_ptr<TileSnapshot> snapshot = store->NewSnapshot();
  EXPECT_EQ(snapshot->checkpoint_version(), 6u);

  // Rewrite every tile (more scans), delete one, add new ones (another lane).
  for (int v = 7; v <= 12; ++v) {
    checkpointer.MarkDirty(Apply(*map, *MakeScan(params, v % 2 == 0 ? 0 : 3, v), v));
  }
  const TileKey deleted = keys_at_six.front();
  map->EraseTile(deleted);
  checkpointer.MarkDirty({deleted});
  ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
  ASSERT_EQ(store->checkpoint_version(), 12u);
  ASSERT_NE(Keys(*store->ListTiles()), keys_at_six);
  ASSERT_EQ(store->LoadTile(deleted)->get(), nullptr);

  // The snapshot still holds the map at version 6, bit for bit.
  EXPECT_EQ(snapshot->checkpoint_version(), 6u);
  EXPECT_EQ(Keys(*snapshot->ListTiles()), keys_at_six);
  for (TileKey k : keys_at_six) {
    Result<std::unique_ptr<Tile>> tile = snapshot->LoadTile(k);
    ASSERT_TRUE(tile.ok()) << tile.status().ToString();
    ASSERT_NE(tile->get(), nullptr);
    EXPECT_TRUE(**tile == *at_six->FindTile(k)) << k.x << ", " << k.y;
  }
  // A tile the later checkpoint added is not in the view.
  map->ForEachTile([&](TileKey k, const Tile&) {
    if (at_six->FindTile(k) == nullptr) {
      EXPECT_EQ(snapshot->LoadTile(k)->get(), nullptr);
    }
  });
  // A region listing is the region of the view.
  const TileKey min = keys_at_six[1], max = keys_at_six[keys_at_six.size() - 2];
  std::vector<TileKey> expected;
  for (TileKey k : keys_at_six) {
    if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) expected.push_back(k);
  }
  EXPECT_EQ(Keys(*snapshot->ListTiles(min, max)), expected);

  // A new snapshot sees the new state.
  std::unique_ptr<TileSnapshot> later = store->NewSnapshot();
  EXPECT_EQ(later->checkpoint_version(), 12u);
  EXPECT_EQ(Keys(*later->ListTiles()), Keys(*store->ListTiles()));
}

TEST(TileSnapshotTest, SnapshotsOfAStoreSurviveItsFlushAndCompaction) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), {}, params)).value();
  auto map = NewMap(params);
  Checkpointer checkpointer;
  for (int v = 1; v <= 4; ++v) checkpointer.MarkDirty(Apply(*map, *MakeScan(params, 1, v), v));
  ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
  std::unique_ptr<TileSnapshot> snapshot = store->NewSnapshot();
  for (int v = 5; v <= 8; ++v) checkpointer.MarkDirty(Apply(*map, *MakeScan(params, 1, v), v));
  ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
  ASSERT_TRUE(store->Compact().ok());  // the old versions must survive compaction
  const std::vector<StoredTileInfo> tiles = *snapshot->ListTiles();
  ASSERT_FALSE(tiles.empty());
  for (const StoredTileInfo& info : tiles) {
    EXPECT_LE(info.version, 4u);
    Result<std::unique_ptr<Tile>> tile = snapshot->LoadTile(info.key);
    ASSERT_TRUE(tile.ok() && tile->get() != nullptr);
    EXPECT_LE((*tile)->version(), 4u);
  }
}

}  // namespace
}  // namespace bgkmap::storage
