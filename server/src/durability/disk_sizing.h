// The store's sizing rule (docs/storage.md, "Sizing"): what the data directory's file system
// must hold for the store to stay within its bound for months. bgkmapd checks it at start
// against the disk it is given and warns, naming the numbers, when the disk is smaller.
#pragma once

#include <cstdint>
#include <string>

namespace bgkmap {

struct DiskSizing {
  uint64_t retention_bytes = 0;  // storage.retention_mb: scans and history kept for corrections
  uint64_t journal_bytes = 0;    // the log between checkpoints: half the retention at most
  uint64_t wal_bytes = 0;        // RocksDB's write-ahead log: twice the memory-table budget
  uint64_t map_bytes = 0;        // three times the stored tiles, as found at start
  // Files being written by a flush or a compaction, and the files that straddle retention's
  // horizon until their compaction: the memory-table budget; and RocksDB's information log.
  uint64_t transient_bytes = 0;
  uint64_t reserve_bytes = 0;  // storage.min_free_space_mb
  uint64_t total() const {
    return retention_bytes + journal_bytes + wal_bytes + map_bytes + transient_bytes +
           reserve_bytes;
  }
};

// The rule for a store with these settings whose tiles take `map_bytes` now.
DiskSizing SizingFor(uint64_t retention_mb, uint64_t min_free_space_mb, uint64_t memtable_bytes,
                     uint64_t map_bytes);

// "" if `available` (free bytes plus what the store already holds) meets the rule; otherwise
// the one-line warning naming each term, e.g. "the data dir's file system has 300 MB for the
// store, the sizing rule asks 1725 MB: retention 1024 + journal 512 + write-ahead log 64 + map
// 61 + reserve 64 (storage.retention_mb, storage.min_free_space_mb)".
std::string CheckSizing(const DiskSizing& sizing, uint64_t available);

}  // namespace bgkmap
