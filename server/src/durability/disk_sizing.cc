#include "durability/disk_sizing.h"

namespace bgkmap {
namespace {

// What is asked is rounded up, what is there down: a shortfall never reads as "1725 of 1725".
std::string Mb(uint64_t bytes) { return std::to_string((bytes + (1 << 20) - 1) >> 20); }
std::string MbDown(uint64_t bytes) { return std::to_string(bytes >> 20); }

}  // namespace

DiskSizing SizingFor(uint64_t retention_mb, uint64_t min_free_space_mb, uint64_t memtable_bytes,
                     uint64_t map_bytes) {
  DiskSizing s;
  s.retention_bytes = retention_mb << 20;
  // Retention trims only at checkpoints; one is forced once half the bound was written since
  // the last (StoreDurability::checkpoint_due_by_size), so the journal adds half the bound.
  s.journal_bytes = s.retention_bytes / 2;
  // The log is flushed past one memory budget (store_db.cc); writes go on while it flushes.
  s.wal_bytes = 2 * memtable_bytes;
  // A checkpoint writes its tiles anew and their previous copies to the history before
  // retention trims; the tiles' older copies wait for a compaction: a map whose every tile
  // changed stands three times on disk for a moment.
  s.map_bytes = 3 * map_bytes;
  // A flush writes its table file while the log still holds the same records, and a file that
  // straddles retention's horizon keeps its dropped part until compacted: up to one memory
  // budget between them. Plus RocksDB's own files: LOG and LOG.old (storage/src/info_log.h:
  // 2 MB each) and its manifest (max_manifest_file_size, 4 MB; store_db.cc).
  s.transient_bytes = memtable_bytes + (uint64_t{8} << 20);
  s.reserve_bytes = min_free_space_mb << 20;
  return s;
}

std::string CheckSizing(const DiskSizing& s, uint64_t available) {
  if (available >= s.total()) return "";
  return "the data dir's file system has " + MbDown(available) +
         " MB for the store, the sizing rule asks " + Mb(s.total()) + " MB: retention " +
         Mb(s.retention_bytes) + " + journal " + Mb(s.journal_bytes) + " + write-ahead log " +
         Mb(s.wal_bytes) + " + map " + Mb(s.map_bytes) + " + flushes and logs " +
         Mb(s.transient_bytes) + " + reserve " + Mb(s.reserve_bytes) +
         " (storage.retention_mb, storage.min_free_space_mb)";
}

}  // namespace bgkmap
