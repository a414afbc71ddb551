// Store format versions (docs/storage.md "Format versions") and forgetting's stamps on disk: a
// store written by the previous release (format 3, no half_life_s key) opens and upgrades; a newer
// one is refused with one line naming both versions; a forgetting map's stamps survive a
// checkpoint and the log's replay bitwise.
#include <gtest/gtest.h>
#include <rocksdb/db.h>

#include <optional>

#include "../support/raw_store.h"
#include "bgkmap/storage/map_metadata.h"
#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using namespace testing;  // NOLINT

// Sets (or, with nullopt, deletes) `key` of the meta family, with RocksDB directly.
void EditMeta(const std::string& dir, const std::string& key,
              const std::optional<std::string>& value, std::string* old = nullptr) {
  bgkmap::testing::RawStore store(dir);
  ASSERT_NE(store.db(), nullptr) << "cannot open " << dir << ": " << store.error();
  rocksdb::DB* db = store.db();
  rocksdb::ColumnFamilyHandle* meta = store.Family("meta");
  ASSERT_NE(meta, nullptr);
  if (old != nullptr) {
    ASSERT_TRUE(db->Get(rocksdb::ReadOptions(), meta, key, old).ok());
  }
  if (value.has_value()) {
    ASSERT_TRUE(db->Put(rocksdb::WriteOptions(), meta, key, *value).ok());
  } else if (old == nullptr) {
    ASSERT_TRUE(db->Delete(rocksdb::WriteOptions(), meta, key).ok());
  }
}

std::string MetaFormat(const std::string& dir) {
  std::string format;
  EditMeta(dir, "format", std::nullopt, &format);
  return format;
}

// Mutations checked: kStoreFormat left at 4 fails the upgrade's "5"; the half_life_s key without
// a legacy value fails the open of the old store.
TEST(StoreFormatTest, PreviousReleaseStoresUpgradeAndNewerOnesAreRefusedNamingBoth) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto map = NewMap(params);
  {
    auto store = std::move(TileStore::Open(dir.path(), {}, params)).value();
    Checkpointer checkpointer;
    for (int v = 1; v <= 4; ++v) checkpointer.MarkDirty(Apply(*map, *MakeScan(params, 0, v), v));
    ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
  }
  EXPECT_EQ(MetaFormat(dir.path()), std::to_string(kStoreFormat));
  // As the previous release wrote it: format 3, no forgetting key.
  EditMeta(dir.path(), "format", "3");
  EditMeta(dir.path(), "param/half_life_s", std::nullopt);
  {
    Result<std::unique_ptr<TileStore>> store = TileStore::OpenExisting(dir.path(), {});
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    EXPECT_EQ((*store)->params().half_life_s, 0.0);
    auto back = NewMap((*store)->params());
    ASSERT_TRUE(LoadAllTiles(**store, *back).ok());
    back->set_version(map->version());
    EXPECT_TRUE(MapsIdentical(*map, *back));
  }
  EXPECT_EQ(MetaFormat(dir.path()), "5");
  // Built without forgetting: asking for it is refused naming the key.
  MapParams forgetting = params;
  forgetting.half_life_s = 2;
  Result<std::unique_ptr<TileStore>> refused = TileStore::Open(dir.path(), {}, forgetting);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("half_life_s"), std::string::npos)
      << refused.status().message();
  // A newer store: one line naming both versions.
  EditMeta(dir.path(), "format", "6");
  Result<std::unique_ptr<TileStore>> newer = TileStore::OpenExisting(dir.path(), {});
  ASSERT_FALSE(newer.ok());
  EXPECT_EQ(newer.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(newer.status().message().find("has format 6, newer than this build reads (5)"),
            std::string::npos)
      << newer.status().message();
}

// Two robots, the second's stamps behind the first's; a checkpoint halfway, the rest only in the
// log. Recovery gives bitwise the uninterrupted map, stamps included.
// Mutation checked: the log decoder not putting the record's stamp on the scan fails it.
TEST(StoreFormatTest, AForgettingMapRecoversBitwiseWithItsStamps) {
  TempDir dir;
  MapParams params = SmallParams();
  params.half_life_s = 0.5;
  auto map = NewMap(params);
  {
    auto store = std::move(TileStore::Open(dir.path(), {}, params)).value();
    Checkpointer checkpointer;
    for (int v = 1; v <= 12; ++v) {
      auto scan = std::make_shared<PreparedScan>(*MakeScan(params, v % 2, v));
      scan->stamp_ns = int64_t{1'000'000'000} * (v % 2 == 0 ? 10 : 9) + v * 100'000'000;
      checkpointer.MarkDirty(Apply(*map, *scan, v));
      ASSERT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, scan, scan->stamp_ns)).ok());
      if (v == 6) {
        ASSERT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
      }
    }
  }
  int stamped = 0;
  map->ForEachTile([&](TileKey, const Tile& t) { stamped += t.stamp_ns() != 0 ? 1 : 0; });
  EXPECT_GT(stamped, 0);
  auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  EXPECT_EQ(store->params().half_life_s, 0.5);
  auto recovered = NewMap(store->params());
  Result<RecoveryReport> report = RecoverMap(*store, *recovered);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_TRUE(LoadAllTiles(*store, *recovered).ok());
  EXPECT_TRUE(MapsIdentical(*map, *recovered));
}

}  // namespace
}  // namespace bgkmap::storage
