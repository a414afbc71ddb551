// Flips bytes in stored tile values, in log records and in the RocksDB files on disk: every
// damaged tile or record is reported as DataLoss naming it, and everything else is served
// unchanged.
#include <gtest/gtest.h>
#include <rocksdb/db.h>

#include <filesystem>
#include <fstream>

#include "../support/raw_store.h"
#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_snapshot.h"
#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::Checkpointer;
using testing::MakeScan;
using testing::NewMap;
using testing::SmallParams;
using testing::TempDir;

// Bytes of the store's key layout (src/store_keys.h), spelled out: the test edits the database
// underneath the store, as a disk error would.
std::string TileKeyBytes(TileKey k) {
  std::string out;
  for (int v : {k.x, k.y}) {
    const uint32_t biased = static_cast<uint32_t>(v) ^ 0x80000000u;
    for (int i = 3; i >= 0; --i) out.push_back(static_cast<char>((biased >> (8 * i)) & 0xFF));
  }
  return out;
}

std::string VersionKeyBytes(uint64_t v) {
  std::string out;
  for (int i = 7; i >= 0; --i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  return out;
}

// Flips one byte of the value under `key` in column family `family`, with RocksDB directly.
void FlipStoredByte(const std::string& dir, const std::string& family, const std::string& key,
                    size_t offset) {
  bgkmap::testing::RawStore store(dir);
  ASSERT_NE(store.db(), nullptr) << "cannot open " << dir;
  rocksdb::DB* db = store.db();
  rocksdb::ColumnFamilyHandle* target = store.Family(family);
  ASSERT_NE(target, nullptr);
  std::string value;
  ASSERT_TRUE(db->Get(rocksdb::ReadOptions(), target, key, &value).ok());
  value[offset % value.size()] ^= 0x20;
  ASSERT_TRUE(db->Put(rocksdb::WriteOptions(), target, key, value).ok());
}

// A store holding the checkpoint of 12 scans and the log of 6 more; returns the full map.
std::unique_ptr<TerrainMap> BuildStore(const std::string& dir) {
  const MapParams params = SmallParams();
  auto map = NewMap(params);
  auto store = std::move(TileStore::Open(dir, {}, params)).value();
  Checkpointer checkpointer;
  for (int v = 1; v <= 18; ++v) {
    const auto scan = MakeScan(params, v % 2, v);
    checkpointer.MarkDirty(Apply(*map, *scan, v));
    EXPECT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, scan)).ok());
    if (v == 12) {
      EXPECT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
    }
  }
  EXPECT_TRUE(store->Compact().ok());  // tiles into SST files on disk
  return map;
}

// Loads every listed tile; returns the keys that failed, checking the others against `want`
// as of the checkpoint (tiles with version <= 12 are unchanged since).
std::vector<TileKey> LoadAllAndCompare(const TileStore& store, const TerrainMap& at_checkpoint) {
  std::vector<TileKey> failed;
  const Result<std::vector<StoredTileInfo>> listed = store.ListTiles();
  EXPECT_TRUE(listed.ok());
  for (const StoredTileInfo& info : *listed) {
    auto tile = store.LoadTile(info.key);
    if (!tile.ok()) {
      EXPECT_EQ(tile.status().code(), Status::Code::kDataLoss) << tile.status().ToString();
      const std::string name =
          "(" + std::to_string(info.key.x) + ", " + std::to_string(info.key.y) + ")";
      EXPECT_NE(tile.status().message().find(name), std::string::npos) << tile.status().message();
      failed.push_back(info.key);
      continue;
    }
    const Tile* want = at_checkpoint.FindTile(info.key);
    EXPECT_TRUE(*tile && want && **tile == *want) << info.key.x << "," << info.key.y;
  }
  return failed;
}

std::unique_ptr<TerrainMap> MapAtVersion(uint64_t version) {
  const MapParams params = SmallParams();
  auto map = NewMap(params);
  for (uint64_t v = 1; v <= version; ++v) Apply(*map, *MakeScan(params, v % 2, v), v);
  return map;
}

TEST(CorruptionTest, FlippedTileValueIsDataLossAndOtherTilesServe) {
  TempDir dir;
  BuildStore(dir.path());
  const auto at_checkpoint = MapAtVersion(12);
  TileKey victim;
  {
    auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
    victim = store->ListTiles()->at(3).key;
  }
  FlipStoredByte(dir.path(), "tiles", TileKeyBytes(victim), 40);

  auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  EXPECT_EQ(LoadAllAndCompare(*store, *at_checkpoint), std::vector<TileKey>{victim});
  EXPECT_EQ(store->CorruptTiles(), std::vector<TileKey>{victim});
  EXPECT_EQ(store->counters().corrupt_tiles, 1u);

  // Recovery goes on around it and says so; a checkpoint rewriting the tile heals it.
  auto map = NewMap(store->params());
  auto report = RecoverMap(*store, *map);
  ASSERT_TRUE(report.ok());
  ASSERT_TRUE(LoadAllTiles(*store, *map).ok());
  const Tile* healthy = at_checkpoint->FindTile(victim);
  const TileUpdate rewrite{victim, healthy};
  ASSERT_TRUE(store->Checkpoint(store->checkpoint_version(), {&rewrite, 1}).ok());
  EXPECT_TRUE(store->CorruptTiles().empty());
  EXPECT_TRUE(store->LoadTile(victim).ok());
}

TEST(CorruptionTest, FlippedTileValueReadThroughASnapshotIsDataLossNamingIt) {
  TempDir dir;
  BuildStore(dir.path());
  TileKey victim;
  {
    auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
    victim = store->ListTiles()->at(2).key;
  }
  FlipStoredByte(dir.path(), "tiles", TileKeyBytes(victim), 40);

  auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  std::unique_ptr<TileSnapshot> snapshot = store->NewSnapshot();
  Result<std::unique_ptr<Tile>> bad = snapshot->LoadTile(victim);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Status::Code::kDataLoss);
  const std::string name = "tile (" + std::to_string(victim.x) + ", " + std::to_string(victim.y);
  EXPECT_NE(bad.status().message().find(name), std::string::npos) << bad.status().message();
  // Only the store's own reads list a tile as corrupt; other tiles load through the snapshot.
  EXPECT_TRUE(store->CorruptTiles().empty());
  const std::vector<StoredTileInfo> listed = *snapshot->ListTiles();
  for (const StoredTileInfo& t : listed) {
    if (t.key != victim) {
      EXPECT_TRUE(snapshot->LoadTile(t.key).ok());
    }
  }
}

TEST(CorruptionTest, FlippedLogRecordIsSkippedAndReported) {
  TempDir dir;
  BuildStore(dir.path());
  FlipStoredByte(dir.path(), "log", VersionKeyBytes(15), 100);
  auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  auto map = NewMap(store->params());
  auto report = RecoverMap(*store, *map);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->corrupt_records, std::vector<uint64_t>{15});
  EXPECT_EQ(report->scans_replayed, 5u);  // 13, 14, 16, 17, 18
  EXPECT_FALSE(report->clean());
  EXPECT_EQ(store->counters().corrupt_log_records, 1u);
  EXPECT_EQ(map->version(), 18u);
}

// The largest SST file of the store: the tiles (every other family is far smaller).
std::filesystem::path LargestSst(const std::string& dir) {
  std::filesystem::path best;
  uintmax_t best_size = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".sst" && e.file_size() > best_size) {
      best = e.path();
      best_size = e.file_size();
    }
  }
  return best;
}

TEST(CorruptionTest, FlippedBytesInTheTileFileAreDetectedPerTile) {
  const auto at_checkpoint = MapAtVersion(12);
  for (double where : {0.01, 0.2, 0.45}) {
    TempDir dir;
    BuildStore(dir.path());
    const auto sst = LargestSst(dir.path());
    ASSERT_FALSE(sst.empty());
    {
      std::fstream f(sst, std::ios::in | std::ios::out | std::ios::binary);
      const auto offset = static_cast<std::streamoff>(where * std::filesystem::file_size(sst));
      f.seekg(offset);
      char c;
      f.read(&c, 1);
      c = static_cast<char>(c ^ 0x5a);
      f.seekp(offset);
      f.write(&c, 1);
    }
    auto store = TileStore::OpenExisting(dir.path(), {});
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    const std::vector<TileKey> failed = LoadAllAndCompare(**store, *at_checkpoint);
    EXPECT_GE(failed.size(), 1u) << "flip at " << where << " went unnoticed";
    EXPECT_LT(failed.size(), (*store)->ListTiles()->size() / 2) << "one block, not the file";
    EXPECT_EQ((*store)->CorruptTiles(), failed);
  }
}

}  // namespace
}  // namespace bgkmap::storage
