// How a TileStore is opened: durability of the scan log, compression, caches.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string_view>

#include "bgkmap/core/status.h"
#include "bgkmap/storage/free_space.h"
#include "bgkmap/storage/tile_codec.h"

namespace rocksdb {
class FileSystem;
}

namespace bgkmap::storage {

// When an appended log record counts as durable (docs/storage.md, "Durability").
enum class Durability {
  // Append returns after the record is fsync'ed. Concurrent appenders share one fsync
  // (RocksDB's write group), so throughput grows with the number of writers.
  kSync,
  // Append returns once the record is in the operating system's page cache: it survives a
  // kill -9 of the process at once, and a power loss or kernel crash once the background
  // sync has run, i.e. within periodic_sync_ms.
  kPeriodic,
};

std::string_view DurabilityName(Durability d);         // "sync" | "periodic"
Result<Durability> ParseDurability(std::string_view);  // the YAML value, e.g. "sync"

enum class TileCompression { kNone, kLz4, kZstd };

struct StoreOptions {
  Durability durability = Durability::kSync;
  uint32_t periodic_sync_ms = 100;  // kPeriodic: the power-loss window
  bool create_if_missing = true;    // Open() of an empty directory creates the store
  // RocksDB's own memory: the block cache, and the memory tables of every column family
  // together (writes flush to files beyond it). A server's fixed overhead, whatever the map.
  size_t block_cache_bytes = size_t{32} << 20;
  size_t memtable_bytes = size_t{32} << 20;
  TileCompression tile_compression = TileCompression::kZstd;
  int zstd_level = 3;  // higher levels buy ~3% on real tiles for several times the CPU
  TileEncodeOptions tile_encoding;
  // Every file of the store is read and written through this file system; null: the
  // operating system's (RocksDB's default). For fault injection in tests only, e.g.
  // tests/storage/power_cut_file_system.h, which forgets what was not fsync'ed.
  std::shared_ptr<rocksdb::FileSystem> file_system;
  // The free-space reserve (free_space.h): every write (append, checkpoint, robot retirement)
  // is refused with IoError while it would leave less than reserve_bytes free on the store's
  // file system, and a store opened with less than that free opens read-only (writes refused
  // until Resume() finds the space back). reserve_bytes 0: no reserve.
  FreeSpaceOptions free_space;
  // What the store keeps for pose corrections (scan_history.h). max_bytes 0: nothing is kept
  // (the log ends at the last checkpoint, no scan can be corrected).
  struct Retention {
    // Bound on the raw scans, log records and tile history kept for corrections (RocksDB's
    // estimate of their files and memory tables), enforced at each checkpoint; the dropped
    // ranges are compacted away at once (TileStore::Checkpoint).
    uint64_t max_bytes = 0;
    // Bound on their age in map time: scans older than this before the newest scan's stamp are
    // dropped at the next checkpoint. 0: no bound by age.
    int64_t max_age_ns = 0;
    bool enabled() const { return max_bytes > 0; }
  } retention;
};

}  // namespace bgkmap::storage
