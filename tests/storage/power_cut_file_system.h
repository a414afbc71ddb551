// A rocksdb::FileSystem for tests that does to files what a power cut does: what was written but
// not fsync'ed is gone. Used as StoreOptions::file_system (power_cut_test.cc).
//
// Every file written through it is tracked: its size, and its size when its last Sync() or
// Fsync() started (only those count: RocksDB's RangeSync is sync_file_range, no durability
// barrier). A power cut has two steps:
//   CutPower()        the machine stops at this instant: every later write, sync, rename,
//                     deletion or truncation through this file system is dropped (and reported
//                     as done, as nobody is left to see otherwise). Destroy the store after it.
//   LoseUnsyncedData() then truncates every tracked file to its synced size and deletes the files
//                     that were never synced, as the disk holds them after the reboot.
// Not modelled: directory entries (a file, rename or deletion is taken as durable once done;
// RocksDB fsyncs the directory after each), partially persisted unsynced data (all of it is lost,
// the worst case), and files that existed before this file system was used (left as they are).
//
// It also counts the syncs of write-ahead log files (`*.log`), so a test can tell which
// acknowledgements a completed log sync covered.
#pragma once

#include <rocksdb/file_system.h>

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace bgkmap::storage::testing {

class PowerCutFileSystem : public rocksdb::FileSystemWrapper {
 public:
  explicit PowerCutFileSystem(
      std::shared_ptr<rocksdb::FileSystem> base = rocksdb::FileSystem::Default());

  const char* Name() const override { return "PowerCutFileSystem"; }

  void CutPower();
  bool power_is_cut() const { return cut_.load(); }
  // After CutPower() and once the store is destroyed. Returns the bytes lost; of those, the
  // write-ahead log's are in lost_wal_bytes().
  uint64_t LoseUnsyncedData();
  uint64_t lost_wal_bytes() const { return lost_wal_bytes_; }

  // Write-ahead log syncs: a ticket is drawn when one starts (1, 2, ...); the highest ticket of
  // a completed one. A record acknowledged when the last drawn ticket was t is on the disk once a
  // sync with a ticket above t has completed.
  uint64_t wal_syncs_started() const { return wal_sync_started_.load(); }
  uint64_t wal_syncs_completed() const { return wal_sync_completed_.load(); }

  // ---- rocksdb::FileSystem
  rocksdb::IOStatus NewWritableFile(const std::string& name, const rocksdb::FileOptions& options,
                                    std::unique_ptr<rocksdb::FSWritableFile>* result,
                                    rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus ReopenWritableFile(const std::string& name, const rocksdb::FileOptions& options,
                                       std::unique_ptr<rocksdb::FSWritableFile>* result,
                                       rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus ReuseWritableFile(const std::string& name, const std::string& old_name,
                                      const rocksdb::FileOptions& options,
                                      std::unique_ptr<rocksdb::FSWritableFile>* result,
                                      rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus NewRandomRWFile(const std::string& name, const rocksdb::FileOptions& options,
                                    std::unique_ptr<rocksdb::FSRandomRWFile>* result,
                                    rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus DeleteFile(const std::string& name, const rocksdb::IOOptions& options,
                               rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus RenameFile(const std::string& from, const std::string& to,
                               const rocksdb::IOOptions& options,
                               rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus LinkFile(const std::string& from, const std::string& to,
                             const rocksdb::IOOptions& options,
                             rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus Truncate(const std::string& name, size_t size,
                             const rocksdb::IOOptions& options,
                             rocksdb::IODebugContext* dbg) override;
  rocksdb::IOStatus DeleteDir(const std::string& name, const rocksdb::IOOptions& options,
                              rocksdb::IODebugContext* dbg) override;

  // What is known of one written file; shared with its open handle, so a rename while it is
  // open keeps counting under the new name.
  struct FileState {
    uint64_t size = 0;
    uint64_t synced = 0;
    bool ever_synced = false;
  };

 private:
  friend class PowerCutWritableFile;
  std::shared_ptr<FileState> Track(const std::string& name, uint64_t size, bool durable);
  bool IsWal(const std::string& name) const;

  std::atomic<bool> cut_{false};
  std::atomic<uint64_t> wal_sync_started_{0}, wal_sync_completed_{0};
  uint64_t lost_wal_bytes_ = 0;
  std::mutex mu_;  // guards files_ and every FileState
  std::map<std::string, std::shared_ptr<FileState>> files_;
};

}  // namespace bgkmap::storage::testing
