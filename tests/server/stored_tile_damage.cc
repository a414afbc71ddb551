#include "stored_tile_damage.h"

#include <gtest/gtest.h>
#include <rocksdb/db.h>

#include <memory>
#include <vector>

#include "../support/raw_store.h"
#include "bgkmap/storage/tile_store.h"

namespace bgkmap::testing {

TileKey CorruptStoredTile(const std::string& dir, StoredTilePick pick) {
  {
    auto store = storage::TileStore::OpenExisting(dir, {});
    EXPECT_TRUE(store.ok()) << store.status().ToString();
    EXPECT_TRUE(store.ok() && (*store)->Compact().ok());
  }
  RawStore store(dir);
  EXPECT_NE(store.db(), nullptr) << "cannot open " << dir;
  rocksdb::DB* db = store.db();
  rocksdb::ColumnFamilyHandle* tiles = store.Family("tiles");
  std::vector<std::string> keys;
  if (tiles != nullptr) {
    std::unique_ptr<rocksdb::Iterator> it(db->NewIterator(rocksdb::ReadOptions(), tiles));
    for (it->SeekToFirst(); it->Valid(); it->Next()) keys.push_back(it->key().ToString());
  }
  TileKey key;
  if (keys.empty()) {
    ADD_FAILURE() << "no stored tile in " << dir;
  } else {
    const std::string& k = pick == StoredTilePick::kFirst ? keys.front() : keys[keys.size() / 2];
    std::string value;
    EXPECT_TRUE(db->Get(rocksdb::ReadOptions(), tiles, k, &value).ok());
    value[value.size() / 2] ^= 0x20;
    EXPECT_TRUE(db->Put(rocksdb::WriteOptions(), tiles, k, value).ok());
    // The store's key layout: x and y as big-endian u32 with the sign bit flipped.
    auto coord = [&](size_t at) {
      uint32_t v = 0;
      for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<uint8_t>(k[at + i]);
      return static_cast<int>(v ^ 0x80000000u);
    };
    key = {coord(0), coord(4)};
  }
  return key;
}

}  // namespace bgkmap::testing
