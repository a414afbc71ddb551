// The scan log: the durability mechanism of the map. Every applied change (a scan's training
// set, or a region clear) is appended as one LogRecord keyed by its map version, in the same
// atomic write as the robot's sequence number and the map version. A checkpoint (TileStore::
// Checkpoint) later writes the tiles and deletes the records it covers; recovery replays the
// records after the last checkpoint in version order (recovery.h).
//
// Owned by a TileStore; obtain it with TileStore::log(). Thread-safe.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"
#include "bgkmap/storage/free_space.h"
#include "bgkmap/storage/log_record.h"
#include "bgkmap/storage/store_options.h"

namespace rocksdb {
class WriteBatch;
}

namespace bgkmap::storage {

struct StoreDb;

struct LogStats {
  uint64_t records = 0;
  uint64_t bytes = 0;          // encoded record bytes
  uint64_t first_version = 0;  // 0 when empty
  uint64_t last_version = 0;
};

class ScanLog {
 public:
  ~ScanLog();  // stops the periodic sync after a last one

  ScanLog(const ScanLog&) = delete;
  ScanLog& operator=(const ScanLog&) = delete;

  // Appends `record` (and its raw scan, record.raw_scan, when the store retains them) and, for a
  // scan, max-merges the robot's last sequence number; the map
  // version is max-merged too. Returns once the record is durable as the store's Durability
  // says; only then may the change be acknowledged. Concurrent appends share fsyncs.
  //   InvalidArgument: version 0, a version at or below the last checkpoint, or a scan
  //                    record without a scan.
  //   IoError:         the write failed (disk full, I/O error), or was refused before it was
  //                    tried: less than the free-space reserve would stay free, or the store
  //                    is read-only (opened on a full disk). Nothing is acknowledged: the
  //                    caller must refuse the change. Earlier appends are unaffected; a
  //                    refusal for space latches nothing (the next append probes again).
  // Versions must be unique; appending an existing version replaces its record.
  // A scan whose raw scan is kept is logged without its observed cells (cells_in_source): its
  // points are stored once, and reading the record prepares them again (LoadCells).
  Status Append(const LogRecord& record);

  // Calls `visit(version, record)` for each record with version > `after`, in version order.
  // A record that fails its checksum or does not decode is passed as a DataLoss status naming
  // its version (and counted in corrupt_records()); visiting goes on. Stops at the first non-OK
  // status `visit` returns and returns it. An unreadable stretch of the log (a corrupt RocksDB
  // block) ends the walk with DataLoss.
  // With LogRead::kWhole every scan record comes with its observed cells (a record that keeps
  // them in its raw scan is prepared again: a failure, e.g. the raw scan missing or preparing
  // differently, is that record's DataLoss); with kHeaders such a record comes as stored, its
  // scan without cells (cells_in_source set), for readers of the tile lists and headers only.
  enum class LogRead { kWhole, kHeaders };
  using Visitor = std::function<Status(uint64_t version, Result<LogRecord> record)>;
  Status ForEach(uint64_t after, const Visitor& visit, LogRead mode = LogRead::kWhole) const;

  // The prepared scan of `record` (of `version`) with its observed cells: the record's own scan
  // unless cells_in_source, else its raw scan prepared again with the store's parameters and
  // checked against the record (cells' CRC, tile lists, counts). DataLoss naming the version if
  // the raw scan is missing or damaged or prepares differently (a build that prepares scans
  // otherwise than the one that logged it).
  Result<std::shared_ptr<const PreparedScan>> LoadCells(uint64_t version,
                                                        const LogRecord& record) const;

  // The raw scan kept beside the record of `version` (StoreOptions::retention); nullopt if none
  // is kept (retention off, or dropped). DataLoss if it fails its checksum.
  Result<std::optional<RawScan>> LoadRawScan(uint64_t version) const;

  // Counts the records after `after` (reads them).
  Result<LogStats> Stats(uint64_t after = 0) const;

  // Highest version appended or found in the store at open (0: none).
  uint64_t last_version() const;
  // Last sequence number logged for `robot_id`; nullopt if the robot never logged a scan.
  std::optional<uint64_t> LastSequence(std::string_view robot_id) const;
  std::map<std::string, uint64_t> RobotSequences() const;
  // Forgets `robot_id` (its last sequence number), durably (fsync'ed): its next scan starts a
  // new sequence. Records already logged stay (they replay as map changes). Call when no scan of
  // the robot is being appended. IoError if the write fails (latched like a failed append).
  Status RetireRobot(std::string_view robot_id);

  // Makes every appended record durable now (fsync of the write-ahead log). After a failed
  // write, returns that failure without touching the log file again (RocksDB must not sync a
  // log writer that has failed) until TileStore::Resume() succeeds.
  Status Sync();

  // The first write failure since open or the last successful resume; OK if none.
  Status write_failure() const;

  Durability durability() const { return durability_; }
  uint64_t records_appended() const { return appended_.load(); }
  uint64_t bytes_appended() const { return appended_bytes_.load(); }
  // Bytes written to the database by appends (records and raw scans) since the last
  // checkpoint: what a checkpoint would let retention trim (TileStore::Checkpoint).
  uint64_t bytes_since_checkpoint() const {
    return written_bytes_.load() - written_at_checkpoint_.load();
  }
  uint64_t corrupt_records() const { return corrupt_.load(); }
  uint64_t append_errors() const { return append_errors_.load(); }
  // Writes refused by the free-space reserve or because the store is read-only.
  uint64_t space_refusals() const { return space_refusals_.load(); }
  bool read_only() const { return read_only_; }

 private:
  friend class TileStore;
  // `guard`: the store's free-space reserve (outlives the log). `read_only`: the database was
  // opened read-only, every write is refused.
  ScanLog(StoreDb* db, const StoreOptions& options, const MapParams& params, uint64_t map_version,
          std::map<std::string, uint64_t> robots, uint64_t checkpoint_version,
          FreeSpaceGuard* guard, bool read_only);

  // OK if `bytes` may be written now (the reserve stays free, the store is writable); the
  // refusal otherwise, counted. Checked before every write to the database.
  Status AdmitWrite(uint64_t bytes);
  // AdmitWrite() for a write that frees more than it adds (FreeSpaceGuard::AdmitFreeing).
  Status AdmitFreeingWrite(uint64_t bytes);
  // The guard's answer `s`, refused if the store is read-only; a refusal is counted.
  Status CountRefusal(Status s);

  // `record` as the log stores it: without its cells when its raw scan is stored beside it.
  std::string EncodeStored(const LogRecord& record) const;
  // Adds to `batch` the deletion of every record (and raw scan) with version <= `through`.
  void AddTruncation(rocksdb::WriteBatch* batch, uint64_t through);
  // `written_before`: written_bytes_ when the checkpoint started (appends may run beside it).
  void OnCheckpoint(uint64_t version, uint64_t written_before) {
    checkpoint_version_.store(version);
    written_at_checkpoint_.store(written_before);
  }
  uint64_t written_bytes() const { return written_bytes_.load(); }
  // A record was written by the store itself (a correction).
  void NoteAppended(uint64_t version) {
    std::lock_guard<std::mutex> lock(mu_);
    last_version_ = std::max(last_version_, version);
  }
  void LatchFailure(const Status& s);
  void ClearFailure();
  void SyncLoop();

  StoreDb* db_;
  FreeSpaceGuard* guard_;
  const bool read_only_;
  const Durability durability_;
  const bool retain_sources_;
  const uint32_t periodic_sync_ms_;
  const MapParams params_;  // the store's: what a scan logged without its cells is prepared with

  std::atomic<uint64_t> checkpoint_version_;
  std::atomic<uint64_t> appended_{0}, appended_bytes_{0};
  std::atomic<uint64_t> written_bytes_{0}, written_at_checkpoint_{0};
  mutable std::atomic<uint64_t> corrupt_{0};
  std::atomic<uint64_t> append_errors_{0};
  std::atomic<uint64_t> space_refusals_{0};

  mutable std::mutex mu_;  // guards last_version_, robots_, failure_
  Status failure_;
  uint64_t last_version_;
  std::map<std::string, uint64_t, std::less<>> robots_;

  std::mutex sync_mu_;  // guards stop_
  std::condition_variable sync_cv_;
  bool stop_ = false;
  std::thread syncer_;
};

}  // namespace bgkmap::storage
