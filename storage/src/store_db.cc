#include "store_db.h"

#include <fcntl.h>
#include <rocksdb/cache.h>
#include <rocksdb/env.h>
#include <rocksdb/filter_policy.h>
#include <rocksdb/table.h>
#include <rocksdb/write_buffer_manager.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>

#include "info_log.h"
#include "max_merge_operator.h"
#include "store_keys.h"

namespace bgkmap::storage {
namespace {

rocksdb::CompressionType ToRocks(TileCompression c) {
  switch (c) {
    case TileCompression::kNone:
      return rocksdb::kNoCompression;
    case TileCompression::kLz4:
      return rocksdb::kLZ4Compression;
    case TileCompression::kZstd:
      return rocksdb::kZSTD;
  }
  return rocksdb::kNoCompression;
}

rocksdb::ColumnFamilyOptions TileFamilyOptions(const StoreOptions& options,
                                               const std::shared_ptr<rocksdb::Cache>& cache) {
  rocksdb::ColumnFamilyOptions cf;
  cf.compression = ToRocks(options.tile_compression);
  cf.bottommost_compression = cf.compression;
  cf.compression_opts.level = options.zstd_level;
  cf.bottommost_compression_opts = cf.compression_opts;
  cf.bottommost_compression_opts.enabled = true;
  rocksdb::BlockBasedTableOptions table;
  table.block_cache = cache;
  // A tile (tens of KB) fills a block on its own; larger blocks would only make a corrupt
  // block take more tiles down with it.
  table.block_size = 16 << 10;
  // Loading a tile that does not exist is common (new ground): let the filter answer it.
  table.filter_policy.reset(rocksdb::NewBloomFilterPolicy(10));
  cf.table_factory.reset(rocksdb::NewBlockBasedTableFactory(table));
  return cf;
}

// Raw scans: large, written once, read only by a correction. LZ4 costs a fraction of zstd's CPU
// on the ingest path (flushes) for most of its gain on float coordinates.
rocksdb::ColumnFamilyOptions SourceFamilyOptions(const std::shared_ptr<rocksdb::Cache>& cache) {
  rocksdb::ColumnFamilyOptions cf;
  cf.compression = rocksdb::kLZ4Compression;
  cf.bottommost_compression = rocksdb::kLZ4Compression;
  rocksdb::BlockBasedTableOptions table;
  table.block_cache = cache;
  table.block_size = 64 << 10;
  cf.table_factory.reset(rocksdb::NewBlockBasedTableFactory(table));
  return cf;
}

// The log, raw scans and tile history are keyed by map version and dropped oldest first, so a
// flush writes a file of consecutive versions and retention drops whole files (ReclaimDropped).
// RocksDB's own compactions would merge them into ever larger files and, while doing so, hold
// their inputs and outputs on disk at once: the transient that broke the disk bound (issue 25).
// Without them, L0's file count does not stall writes (RocksDB ignores it then).
rocksdb::ColumnFamilyOptions VersionKeyedLayout(rocksdb::ColumnFamilyOptions cf) {
  cf.disable_auto_compactions = true;
  return cf;
}

// Every checkpoint rewrites its dirty tiles, and their older copies stay on disk until a
// compaction of level 0 merges them away: at RocksDB's default of four files, a map whose
// tiles are all dirty stood five times on disk. Two keeps it under three.
rocksdb::ColumnFamilyOptions MapLayout(rocksdb::ColumnFamilyOptions cf) {
  cf.level0_file_num_compaction_trigger = 2;
  return cf;
}

}  // namespace

// POSIX record locks do not exclude the process holding them, so, like RocksDB, the
// directories locked in this process are kept here too.
std::mutex locked_mu;
std::set<std::string>& LockedReadOnly() {
  static std::set<std::string> dirs;
  return dirs;
}
std::string LockKey(const std::string& dir) {
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(dir, ec);
  return ec ? dir : p.string();
}

// The lock RocksDB takes on <dir>/LOCK (a POSIX record lock on the whole file), taken by the
// store for a read-only database, which takes none.
Result<int> LockLikeRocksDb(const std::string& dir) {
  std::lock_guard guard(locked_mu);
  if (LockedReadOnly().contains(LockKey(dir))) {
    return Status::IoError("opening the map store in " + dir +
                           ": it is already open (read-only) in this process");
  }
  const std::string path = dir + "/LOCK";
  const int fd = open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) {
    return Status::IoError("opening the map store in " + dir + " read-only: cannot open " + path +
                           ": " + std::strerror(errno));
  }
  struct flock lock = {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (fcntl(fd, F_SETLK, &lock) != 0) {
    const int err = errno;
    close(fd);
    return Status::IoError("opening the map store in " + dir + " read-only: lock " + path + ": " +
                           std::strerror(err) + " (is another server using it?)");
  }
  LockedReadOnly().insert(LockKey(dir));
  return fd;
}

void UnlockReadOnly(const std::string& dir, int fd) {
  std::lock_guard guard(locked_mu);
  LockedReadOnly().erase(LockKey(dir));
  close(fd);
}

StoreDb::~StoreDb() {
  if (db) {
    for (rocksdb::ColumnFamilyHandle* h : handles) db->DestroyColumnFamilyHandle(h);
    db->Close();
  }
  if (read_only_lock_fd >= 0) UnlockReadOnly(dir, read_only_lock_fd);
}

namespace {

// The database's options; its own log goes to InfoLog (or the test's file system to `store`'s
// env).
rocksdb::DBOptions DbOptions(const std::string& dir, const StoreOptions& options, bool read_only,
                             StoreDb& store) {
  rocksdb::DBOptions db_options;
  db_options.create_if_missing = options.create_if_missing;
  // A store of an older format gains the families it lacks when opened for writing.
  db_options.create_missing_column_families = !read_only;
  // A torn last record (the crash came mid-write) is dropped; it was never acknowledged.
  db_options.wal_recovery_mode = rocksdb::WALRecoveryMode::kPointInTimeRecovery;
  db_options.paranoid_checks = true;
  db_options.max_background_jobs = 2;
  // RocksDB preallocates each write-ahead log file (1.1 x the memory budget, 35 MB): blocks the
  // file system counts as used and the file's size does not show, so the reserve found 35 MB
  // gone on an empty store and the byte bound missed them (docs/storage.md, "Sizing").
  db_options.allow_fallocate = false;
  // RocksDB's manifest records every file added and deleted; it starts over (from a snapshot
  // of the live files) only past max_manifest_file_size, 1 GB by default: months of flushes.
  db_options.max_manifest_file_size = 4 << 20;
  if (options.file_system) {
    store.env = rocksdb::NewCompositeEnv(options.file_system);
    db_options.env = store.env.get();
  } else {
    std::error_code ec;
    if (options.create_if_missing && !read_only) std::filesystem::create_directories(dir, ec);
    // Not RocksDB's own log file, which aborts the process on a full disk (info_log.h).
    if (std::filesystem::is_directory(dir, ec)) db_options.info_log = InfoLog::Open(dir);
  }
  // One budget for the memory tables of all families: the log alone would otherwise hold up to
  // 2 x 64 MiB of records between checkpoints, and the tiles as much again.
  store.write_buffers = std::make_shared<rocksdb::WriteBufferManager>(options.memtable_bytes);
  db_options.write_buffer_manager = store.write_buffers;
  // A write-ahead log file goes only once every family has flushed what it holds; the meta
  // family's few bytes would keep the oldest alive for ever. Past the memory budget, RocksDB
  // flushes the families that hold it; the sizing rule counts twice that, for what arrives
  // while those flushes run (docs/storage.md, "Sizing").
  db_options.max_total_wal_size = options.memtable_bytes;
  return db_options;
}

// The store's column families, in the order of StoreDb's handles.
std::vector<rocksdb::ColumnFamilyDescriptor> Families(const StoreOptions& options) {
  auto cache = rocksdb::NewLRUCache(options.block_cache_bytes);
  rocksdb::ColumnFamilyOptions meta;
  meta.merge_operator = std::make_shared<MaxMergeOperator>();
  rocksdb::ColumnFamilyOptions log;
  // Log records live only until the next checkpoint; compressing them is wasted work.
  log.compression = rocksdb::kNoCompression;
  return {
      {rocksdb::kDefaultColumnFamilyName, rocksdb::ColumnFamilyOptions()},
      {kMetaFamily, meta},
      {kTilesFamily, MapLayout(TileFamilyOptions(options, cache))},
      {kTileIndexFamily, rocksdb::ColumnFamilyOptions()},
      {kLogFamily, VersionKeyedLayout(log)},
      // Raw scans and superseded tiles, kept for corrections (scan_history.h): written once,
      // read rarely, large; compressed like the tiles.
      {kSourcesFamily, VersionKeyedLayout(SourceFamilyOptions(cache))},
      {kHistoryFamily, VersionKeyedLayout(TileFamilyOptions(options, cache))},
  };
}

// A read-only database takes RocksDB's lock itself; a writable one may not open a directory
// this process holds read-only.
Status Lock(const std::string& dir, bool read_only, StoreDb& store) {
  if (read_only) {
    Result<int> fd = LockLikeRocksDb(dir);
    if (!fd.ok()) return fd.status();
    store.read_only_lock_fd = *fd;
    return Status::Ok();
  }
  std::lock_guard guard(locked_mu);
  if (LockedReadOnly().contains(LockKey(dir))) {
    return Status::IoError("opening the map store in " + dir +
                           ": it is already open (read-only) in this process");
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<StoreDb>> StoreDb::Open(const std::string& dir, const StoreOptions& options,
                                               bool read_only) {
  auto store = std::make_unique<StoreDb>();
  const rocksdb::DBOptions db_options = DbOptions(dir, options, read_only, *store);
  std::vector<rocksdb::ColumnFamilyDescriptor> families = Families(options);
  store->dir = dir;
  if (Status s = Lock(dir, read_only, *store); !s.ok()) return s;
  if (read_only) {
    // Read-only cannot create a family: an older store opens without the ones it lacks.
    std::vector<std::string> present;
    if (rocksdb::DB::ListColumnFamilies(db_options, dir, &present).ok()) {
      std::erase_if(families, [&](const rocksdb::ColumnFamilyDescriptor& f) {
        return std::find(present.begin(), present.end(), f.name) == present.end();
      });
    }
  }
  rocksdb::DB* db = nullptr;
  const rocksdb::Status s =
      read_only ? rocksdb::DB::OpenForReadOnly(db_options, dir, families, &store->handles, &db)
                : rocksdb::DB::Open(db_options, dir, families, &store->handles, &db);
  if (!s.ok()) {
    if (s.IsInvalidArgument() && !options.create_if_missing) {
      return Status::FailedPrecondition("no map store in " + dir + ": " + s.ToString());
    }
    return FromRocks(s, "opening the map store in " + dir);
  }
  store->db.reset(db);
  store->meta = store->handles[1];
  store->tiles = store->handles[2];
  store->tile_index = store->handles[3];
  store->log = store->handles[4];
  if (store->handles.size() > 6) {
    store->sources = store->handles[5];
    store->history = store->handles[6];
  }
  return store;
}

Status FromRocks(const rocksdb::Status& s, std::string_view context) {
  if (s.ok()) return Status::Ok();
  std::string message = std::string(context) + ": " + s.ToString();
  if (s.IsCorruption()) return Status::DataLoss(std::move(message));
  if (s.IsNoSpace()) return Status::IoError(std::move(message) + " (disk full)");
  return Status::IoError(std::move(message));
}

}  // namespace bgkmap::storage
