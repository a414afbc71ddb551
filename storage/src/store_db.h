// The open RocksDB database behind a TileStore: the handle, its column families, and the
// conversion of RocksDB statuses into bgkmap ones. Internal to storage/.
#pragma once

#include <rocksdb/db.h>
#include <rocksdb/write_buffer_manager.h>

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/storage/store_options.h"

namespace bgkmap::storage {

struct StoreDb {
  ~StoreDb();  // releases the family handles, then closes the database

  // The environment over StoreOptions::file_system (null: RocksDB's default one). Declared
  // before `db`, so it outlives the database.
  std::unique_ptr<rocksdb::Env> env;
  std::unique_ptr<rocksdb::DB> db;
  std::vector<rocksdb::ColumnFamilyHandle*> handles;
  rocksdb::ColumnFamilyHandle* meta = nullptr;
  rocksdb::ColumnFamilyHandle* tiles = nullptr;
  rocksdb::ColumnFamilyHandle* tile_index = nullptr;
  rocksdb::ColumnFamilyHandle* log = nullptr;
  rocksdb::ColumnFamilyHandle* sources = nullptr;
  rocksdb::ColumnFamilyHandle* history = nullptr;
  // Read-only: the database writes nothing (no log, no flush, no compaction, no lock file), so
  // the store holds its own lock on <dir>/LOCK instead, as RocksDB does, against a second
  // server; -1 when RocksDB holds it.
  int read_only_lock_fd = -1;
  std::string dir;
  // The memory tables' budget, shared by every family; its usage is what a flush will write.
  std::shared_ptr<rocksdb::WriteBufferManager> write_buffers;

  // Opens (creating if allowed) the database in `dir` with every column family. `read_only`:
  // an existing database, for reads only (a full disk: nothing may be written).
  static Result<std::unique_ptr<StoreDb>> Open(const std::string& dir, const StoreOptions& options,
                                               bool read_only = false);
};

// Corruption -> DataLoss; I/O errors (disk full included) -> IoError; anything else ->
// IoError too, since the caller cannot fix it by changing its request. `context` says what was
// being done ("reading tile (3, 4)").
Status FromRocks(const rocksdb::Status& s, std::string_view context);

}  // namespace bgkmap::storage
