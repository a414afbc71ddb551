// A store's RocksDB database opened directly, with every column family: for tests that edit or
// damage what lies underneath the store (corrupt a tile, rewrite a format marker). Closed, its
// handles released, when it goes out of scope.
#pragma once

#include <rocksdb/db.h>

#include <memory>
#include <string>
#include <vector>

namespace bgkmap::testing {

class RawStore {
 public:
  explicit RawStore(const std::string& dir) {
    if (!rocksdb::DB::ListColumnFamilies(rocksdb::DBOptions(), dir, &names_).ok()) return;
    std::vector<rocksdb::ColumnFamilyDescriptor> descriptors;
    for (const auto& n : names_) descriptors.emplace_back(n, rocksdb::ColumnFamilyOptions());
    rocksdb::DB* raw = nullptr;
    if (rocksdb::DB::Open(rocksdb::DBOptions(), dir, descriptors, &handles_, &raw).ok()) {
      db_.reset(raw);
    }
  }
  ~RawStore() {
    if (!db_) return;
    for (auto* h : handles_) db_->DestroyColumnFamilyHandle(h);
    db_->Close();
  }
  RawStore(const RawStore&) = delete;
  RawStore& operator=(const RawStore&) = delete;

  // Null if the store could not be opened.
  rocksdb::DB* db() const { return db_.get(); }
  // Null if there is no such column family.
  rocksdb::ColumnFamilyHandle* Family(const std::string& name) const {
    for (size_t i = 0; db_ && i < names_.size(); ++i) {
      if (names_[i] == name) return handles_[i];
    }
    return nullptr;
  }

 private:
  std::vector<std::string> names_;
  std::vector<rocksdb::ColumnFamilyHandle*> handles_;
  std::unique_ptr<rocksdb::DB> db_;
};

}  // namespace bgkmap::testing
