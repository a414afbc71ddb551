#include "bgkmap/storage/scan_log.h"

#include <rocksdb/write_batch.h>

#include <algorithm>
#include <chrono>
#include <deque>
#include <future>
#include <memory>

#include "bgkmap/storage/raw_scan_codec.h"
#include "store_db.h"
#include "store_keys.h"

namespace bgkmap::storage {

ScanLog::ScanLog(StoreDb* db, const StoreOptions& options, const MapParams& params,
                 uint64_t map_version, std::map<std::string, uint64_t> robots,
                 uint64_t checkpoint_version, FreeSpaceGuard* guard, bool read_only)
    : db_(db),
      guard_(guard),
      read_only_(read_only),
      durability_(options.durability),
      retain_sources_(options.retention.enabled()),
      periodic_sync_ms_(std::max<uint32_t>(1, options.periodic_sync_ms)),
      params_(params),
      checkpoint_version_(checkpoint_version),
      last_version_(map_version),
      robots_(robots.begin(), robots.end()) {
  if (durability_ == Durability::kPeriodic && !read_only_)
    syncer_ = std::thread([this] { SyncLoop(); });
}

ScanLog::~ScanLog() {
  if (syncer_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(sync_mu_);
      stop_ = true;
    }
    sync_cv_.notify_all();
    syncer_.join();
  }
  Sync();  // a clean shutdown leaves nothing in the window
}

void ScanLog::SyncLoop() {
  std::unique_lock<std::mutex> lock(sync_mu_);
  while (!stop_) {
    sync_cv_.wait_for(lock, std::chrono::milliseconds(periodic_sync_ms_));
    if (stop_) break;
    lock.unlock();
    Sync();  // a failure shows up again in the next Append's own write
    lock.lock();
  }
}

Status ScanLog::Sync() {
  if (read_only_) return Status::Ok();  // nothing was written
  if (Status failed = write_failure(); !failed.ok()) return failed;
  Status s = FromRocks(db_->db->FlushWAL(/*sync=*/true), "syncing the log");
  if (!s.ok()) LatchFailure(s);
  return s;
}

Status ScanLog::write_failure() const {
  std::lock_guard<std::mutex> lock(mu_);
  return failure_;
}

Status ScanLog::AdmitWrite(uint64_t bytes) {
  Status s = guard_->Admit(read_only_ ? 0 : bytes);
  return CountRefusal(std::move(s));
}

Status ScanLog::AdmitFreeingWrite(uint64_t bytes) {
  return CountRefusal(guard_->AdmitFreeing(read_only_ ? 0 : bytes));
}

Status ScanLog::CountRefusal(Status s) {
  if (read_only_) {
    // Opened on a full disk (or a reopen for writing failed): TileStore::Resume() reopens it.
    s = Status::IoError("the store is read-only until it can be reopened for writing" +
                        (s.ok() ? std::string(" (there is room again)") : ": " + s.message()));
  }
  if (!s.ok()) space_refusals_.fetch_add(1);
  return s;
}

void ScanLog::LatchFailure(const Status& s) {
  std::lock_guard<std::mutex> lock(mu_);
  if (failure_.ok()) failure_ = s;
}

void ScanLog::ClearFailure() {
  std::lock_guard<std::mutex> lock(mu_);
  failure_ = Status::Ok();
}

Status ScanLog::Append(const LogRecord& record) {
  if (record.version == 0) return Status::InvalidArgument("log record version must be > 0");
  if (record.version <= checkpoint_version_.load()) {
    return Status::InvalidArgument("log record version " + std::to_string(record.version) +
                                   " is at or below the last checkpoint (" +
                                   std::to_string(checkpoint_version_.load()) + ")");
  }
  if (record.type == LogRecord::Type::kScan && !record.scan) {
    return Status::InvalidArgument("scan log record without a scan");
  }
  if (Status failed = write_failure(); !failed.ok()) {
    append_errors_.fetch_add(1);
    return Status::IoError("the store refuses writes since an earlier failure (" +
                           failed.message() + "); TileStore::Resume() once it is fixed");
  }
  const std::string value = EncodeStored(record);
  rocksdb::WriteBatch batch;
  rocksdb::Status s = batch.Put(db_->log, VersionKeyBytes(record.version), value);
  if (s.ok()) s = batch.Merge(db_->meta, kMapVersionKey, U64Bytes(record.version));
  if (s.ok() && record.type == LogRecord::Type::kScan) {
    s = batch.Merge(db_->meta, std::string(kRobotPrefix) + record.robot_id,
                    U64Bytes(record.sequence));
  }
  if (s.ok() && record.raw_scan && retain_sources_ && db_->sources != nullptr) {
    s = batch.Put(db_->sources, VersionKeyBytes(record.version), EncodeRawScan(*record.raw_scan));
  }
  if (!s.ok()) {
    append_errors_.fetch_add(1);
    return FromRocks(s, "appending log record " + std::to_string(record.version));
  }
  // Refused before RocksDB writes a byte: it must never meet a full disk (free_space.h). A
  // clear is an operator freeing space: it may use the upper half of the reserve.
  const uint64_t bytes = batch.GetDataSize();
  if (Status refused =
          record.type == LogRecord::Type::kClear ? AdmitFreeingWrite(bytes) : AdmitWrite(bytes);
      !refused.ok()) {
    return refused;
  }
  rocksdb::WriteOptions write;
  write.sync = durability_ == Durability::kSync;
  s = db_->db->Write(write, &batch);
  if (!s.ok()) {
    append_errors_.fetch_add(1);
    Status failed = FromRocks(s, "appending log record " + std::to_string(record.version));
    LatchFailure(failed);
    return failed;
  }
  appended_.fetch_add(1);
  appended_bytes_.fetch_add(value.size());
  written_bytes_.fetch_add(batch.GetDataSize());
  std::lock_guard<std::mutex> lock(mu_);
  last_version_ = std::max(last_version_, record.version);
  if (record.type == LogRecord::Type::kScan) {
    auto [it, inserted] = robots_.try_emplace(record.robot_id, record.sequence);
    if (!inserted) it->second = std::max(it->second, record.sequence);
  }
  return Status::Ok();
}

std::string ScanLog::EncodeStored(const LogRecord& record) const {
  LogRecord stored = record;
  stored.cells_in_source = record.type == LogRecord::Type::kScan && record.scan &&
                           record.raw_scan && retain_sources_ && db_->sources != nullptr;
  if (stored.cells_in_source) stored.cells_crc = LoggedCellsCrc(*record.scan);
  return EncodeLogRecord(stored);
}

Result<std::shared_ptr<const PreparedScan>> ScanLog::LoadCells(uint64_t version,
                                                               const LogRecord& record) const {
  if (!record.scan) return Status::InvalidArgument("not a scan record");
  if (!record.cells_in_source) return record.scan;
  const std::string where = "log record " + std::to_string(version) + ": ";
  Result<std::optional<RawScan>> raw = LoadRawScan(version);
  if (!raw.ok()) return Status::DataLoss(where + raw.status().message());
  if (!raw->has_value()) {
    return Status::DataLoss(where + "its cells are kept as its raw scan, which is missing");
  }
  const RawScan& source = **raw;
  Result<PreparedScan> prepared =
      PrepareScan(params_, source.points, source.pose, source.frame_is_map);
  if (!prepared.ok()) return Status::DataLoss(where + prepared.status().message());
  // A record written before spans were kept was integrated without them: so it replays.
  if (record.format < kLogFormatWithSpans) {
    for (ObservedCell& cell : prepared->cells) cell.span_mm = 0;
  }
  const PreparedScan& logged = *record.scan;
  if (LoggedCellsCrc(*prepared, record.format) != record.cells_crc ||
      prepared->write_tiles != logged.write_tiles || prepared->read_tiles != logged.read_tiles ||
      prepared->clear_tiles != logged.clear_tiles || prepared->counts.kept != logged.counts.kept) {
    return Status::DataLoss(where +
                            "its raw scan prepares to other cells than were logged (a build "
                            "that prepares scans differently from the one that logged it?)");
  }
  prepared->stamp_ns = record.stamp_ns;
  return std::shared_ptr<const PreparedScan>(
      std::make_shared<PreparedScan>(std::move(prepared).value()));
}

namespace {

// A record read from the log, its cells (if they are kept in its raw scan) being prepared on
// another thread: a replay prepares the next records while it integrates this one.
struct ReadAhead {
  uint64_t version = 0;
  Result<LogRecord> record;
  std::future<Result<std::shared_ptr<const PreparedScan>>> cells;  // invalid: none to prepare
};

// As many records ahead as there are cores to prepare them (at least one).
size_t ReadAheadDepth() { return std::max(1u, std::thread::hardware_concurrency()); }

}  // namespace

Status ScanLog::ForEach(uint64_t after, const Visitor& visit, LogRead mode) const {
  rocksdb::ReadOptions read;
  read.verify_checksums = true;
  read.fill_cache = false;  // a replay reads each record once
  std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(read, db_->log));
  if (after == UINT64_MAX) return Status::Ok();
  std::deque<ReadAhead> ahead;
  // Visits the oldest record read ahead, with its cells.
  auto visit_next = [&]() -> Status {
    ReadAhead next = std::move(ahead.front());
    ahead.pop_front();
    if (next.cells.valid()) {
      Result<std::shared_ptr<const PreparedScan>> whole = next.cells.get();
      if (!whole.ok()) {
        corrupt_.fetch_add(1);  // (its status names the version already)
        return visit(next.version, whole.status());
      }
      next.record->scan = std::move(whole).value();
      next.record->cells_in_source = false;
    }
    return visit(next.version, std::move(next.record));
  };
  for (it->Seek(VersionKeyBytes(after + 1)); it->Valid(); it->Next()) {
    uint64_t version = 0;
    if (!ParseVersionKeyBytes(it->key().ToStringView(), &version)) {
      corrupt_.fetch_add(1);
      continue;  // not a key this format writes; nothing to replay
    }
    Result<LogRecord> record = DecodeLogRecord(it->value().ToStringView());
    if (record.ok() && record->version != version) {
      record = Status::DataLoss("log record stored under version " + std::to_string(version) +
                                " says it is version " + std::to_string(record->version));
    }
    if (!record.ok()) {
      corrupt_.fetch_add(1);
      record = Status::DataLoss("log record " + std::to_string(version) + ": " +
                                record.status().message());
    }
    ReadAhead entry{version, std::move(record), {}};
    if (entry.record.ok() && entry.record->cells_in_source && mode == LogRead::kWhole) {
      entry.cells = std::async(std::launch::async, [this, version, header = *entry.record] {
        return LoadCells(version, header);
      });
    }
    ahead.push_back(std::move(entry));
    if (ahead.size() >= ReadAheadDepth()) {
      if (Status s = visit_next(); !s.ok()) return s;  // (the preparations left are awaited)
    }
  }
  while (!ahead.empty()) {
    if (Status s = visit_next(); !s.ok()) return s;
  }
  if (!it->status().ok()) {
    corrupt_.fetch_add(1);
    return FromRocks(it->status(), "reading the log after version " + std::to_string(after));
  }
  return Status::Ok();
}

Result<LogStats> ScanLog::Stats(uint64_t after) const {
  LogStats stats;
  rocksdb::ReadOptions read;
  read.fill_cache = false;
  std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(read, db_->log));
  for (it->Seek(VersionKeyBytes(after + 1)); it->Valid(); it->Next()) {
    uint64_t version = 0;
    if (!ParseVersionKeyBytes(it->key().ToStringView(), &version)) continue;
    if (stats.records == 0) stats.first_version = version;
    stats.last_version = version;
    ++stats.records;
    stats.bytes += it->value().size();
  }
  if (!it->status().ok()) return FromRocks(it->status(), "reading the log");
  return stats;
}

uint64_t ScanLog::last_version() const {
  std::lock_guard<std::mutex> lock(mu_);
  return last_version_;
}

std::optional<uint64_t> ScanLog::LastSequence(std::string_view robot_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  return it->second;
}

std::map<std::string, uint64_t> ScanLog::RobotSequences() const {
  std::lock_guard<std::mutex> lock(mu_);
  return {robots_.begin(), robots_.end()};
}

Status ScanLog::RetireRobot(std::string_view robot_id) {
  if (Status failed = write_failure(); !failed.ok()) {
    return Status::IoError("the store refuses writes since an earlier failure (" +
                           failed.message() + "); TileStore::Resume() once it is fixed");
  }
  rocksdb::WriteBatch batch;
  rocksdb::Status s = batch.Delete(db_->meta, std::string(kRobotPrefix) + std::string(robot_id));
  if (Status refused = AdmitFreeingWrite(batch.GetDataSize()); !refused.ok()) return refused;
  rocksdb::WriteOptions write;
  write.sync = true;  // an administrator's action: durable when answered, in either mode
  if (s.ok()) s = db_->db->Write(write, &batch);
  if (!s.ok()) {
    Status failed = FromRocks(s, "retiring robot " + std::string(robot_id));
    LatchFailure(failed);
    return failed;
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (auto it = robots_.find(robot_id); it != robots_.end()) robots_.erase(it);
  return Status::Ok();
}

void ScanLog::AddTruncation(rocksdb::WriteBatch* batch, uint64_t through) {
  const std::string end =
      through == UINT64_MAX ? std::string(9, '\xff') : VersionKeyBytes(through + 1);
  batch->DeleteRange(db_->log, VersionKeyBytes(0), end);
  if (db_->sources != nullptr) batch->DeleteRange(db_->sources, VersionKeyBytes(0), end);
}

Result<std::optional<RawScan>> ScanLog::LoadRawScan(uint64_t version) const {
  if (db_->sources == nullptr) return std::optional<RawScan>();
  rocksdb::PinnableSlice value;
  rocksdb::ReadOptions read;
  read.verify_checksums = true;
  const rocksdb::Status s = db_->db->Get(read, db_->sources, VersionKeyBytes(version), &value);
  if (s.IsNotFound()) return std::optional<RawScan>();
  if (!s.ok()) return FromRocks(s, "reading the raw scan of version " + std::to_string(version));
  Result<RawScan> source = DecodeRawScan(value.ToStringView());
  if (!source.ok()) {
    return Status::DataLoss("raw scan of version " + std::to_string(version) + ": " +
                            source.status().message());
  }
  return std::optional<RawScan>(std::move(*source));
}

}  // namespace bgkmap::storage
