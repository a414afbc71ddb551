// The parts of TileStore that keep history for pose corrections: the tiles each checkpoint
// replaced, the retained checkpoints (bases), the retention bound, and rewriting the log.
#include <rocksdb/write_batch.h>

#include <algorithm>
#include <map>

#include "bgkmap/storage/raw_scan_codec.h"
#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/storage/tile_store.h"
#include "store_db.h"
#include "store_keys.h"

namespace bgkmap::storage {
namespace {

std::string HistoryKey(uint64_t checkpoint, TileKey key) {
  return VersionKeyBytes(checkpoint) + TileKeyBytes(key);
}

// The stamp of a log record, read from its header (0 if it does not decode).
int64_t StampOf(std::string_view encoded) {
  Result<LogRecord> record = DecodeLogRecord(encoded);
  return record.ok() ? record->stamp_ns : 0;
}

}  // namespace

std::vector<uint64_t> TileStore::Bases() const {
  std::lock_guard<std::mutex> lock(bases_mu_);
  return bases_;
}

uint64_t TileStore::RetainedBytesAbove(uint64_t version) const {
  const std::string start = VersionKeyBytes(version + 1), limit(9, '\xff');
  rocksdb::Range range(start, limit);
  rocksdb::SizeApproximationOptions options;
  options.include_memtables = true;
  options.include_files = true;
  uint64_t total = 0;
  for (rocksdb::ColumnFamilyHandle* family : {db_->log, db_->sources, db_->history}) {
    if (family == nullptr) continue;
    uint64_t size = 0;
    if (db_->db->GetApproximateSizes(options, family, &range, 1, &size).ok()) total += size;
  }
  return total;
}

int64_t TileStore::FirstStampAbove(uint64_t version) const {
  std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(rocksdb::ReadOptions(), db_->log));
  for (it->Seek(VersionKeyBytes(version + 1)); it->Valid(); it->Next()) {
    if (const int64_t stamp = StampOf(it->value().ToStringView()); stamp != 0) return stamp;
  }
  return 0;
}

int64_t TileStore::LastStamp() const {
  std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(rocksdb::ReadOptions(), db_->log));
  for (it->SeekToLast(); it->Valid(); it->Prev()) {
    if (const int64_t stamp = StampOf(it->value().ToStringView()); stamp != 0) return stamp;
  }
  return 0;
}

Result<std::vector<uint64_t>> TileStore::AddRetention(rocksdb::WriteBatch* batch, uint64_t version,
                                                      std::span<const TileUpdate> tiles,
                                                      bool forget_earlier_bases,
                                                      uint64_t* dropped_through) {
  std::vector<uint64_t> bases = Bases();
  *dropped_through = 0;
  if (!options_.retention.enabled() || db_->history == nullptr) {
    log_->AddTruncation(batch, version);
    *dropped_through = version;
    if (!bases.empty()) {  // retention was switched off: its history goes too
      batch->Delete(db_->meta, kBasesKey);
      batch->DeleteRange(db_->history, std::string(), std::string(17, '\xff'));
    }
    return std::vector<uint64_t>();
  }
  // Without a base (retention switched on for an older store) the history starts here.
  if (!bases.empty()) {
    for (const TileUpdate& update : tiles) {
      rocksdb::PinnableSlice old;
      const rocksdb::Status s =
          db_->db->Get(rocksdb::ReadOptions(), db_->tiles, TileKeyBytes(update.key), &old);
      if (!s.ok() && !s.IsNotFound()) {
        return FromRocks(s, "reading tile " + TileKeyName(update.key) + " for its history");
      }
      batch->Put(db_->history, HistoryKey(version, update.key),
                 s.IsNotFound() ? std::string_view() : old.ToStringView());
    }
  }
  if (forget_earlier_bases) bases.clear();
  uint64_t floor;
  {
    std::lock_guard<std::mutex> lock(bases_mu_);
    floor = bases_floor_;
  }
  // A checkpoint captured before a correction but written after it holds uncorrected tiles.
  if ((bases.empty() || bases.back() < version) && version >= floor) bases.push_back(version);
  if (bases.empty()) return bases;  // (nothing retained yet: keep the log as it is)
  // Drop the oldest bases while what they keep exceeds the bound; the newest always stays.
  const int64_t newest_stamp = options_.retention.max_age_ns > 0 ? LastStamp() : 0;
  while (bases.size() > 1) {
    const bool over_bytes = RetainedBytesAbove(bases.front()) > options_.retention.max_bytes;
    bool over_age = false;
    if (options_.retention.max_age_ns > 0 && newest_stamp != 0) {
      const int64_t first = FirstStampAbove(bases.front());
      over_age = first != 0 && newest_stamp - first > options_.retention.max_age_ns;
    }
    if (!over_bytes && !over_age) break;
    bases.erase(bases.begin());
  }
  const uint64_t horizon = bases.front();
  log_->AddTruncation(batch, horizon);
  *dropped_through = horizon;
  batch->DeleteRange(db_->history, std::string(), VersionKeyBytes(horizon + 1));
  batch->Put(db_->meta, kBasesKey, EncodeVersionList(bases));
  return bases;
}

Result<std::vector<std::unique_ptr<Tile>>> TileStore::LoadTilesAt(
    uint64_t base, std::span<const TileKey> keys) const {
  const std::vector<uint64_t> bases = Bases();
  if (!std::binary_search(bases.begin(), bases.end(), base)) {
    return Status::InvalidArgument("version " + std::to_string(base) +
                                   " is not a retained checkpoint");
  }
  std::map<TileKey, size_t> wanted;
  for (size_t i = 0; i < keys.size(); ++i) wanted.emplace(keys[i], i);
  std::vector<std::unique_ptr<Tile>> out(keys.size());
  std::vector<bool> found(keys.size(), false);
  // One consistent view of the history and the tiles.
  const rocksdb::Snapshot* snapshot = db_->db->GetSnapshot();
  rocksdb::ReadOptions read;
  read.snapshot = snapshot;
  read.verify_checksums = true;
  Status status = Status::Ok();
  {
    // The first replacement after `base` of a tile holds what it was at `base`.
    std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(read, db_->history));
    for (it->Seek(VersionKeyBytes(base + 1)); it->Valid() && status.ok(); it->Next()) {
      const std::string_view k = it->key().ToStringView();
      TileKey key;
      if (k.size() != 16 || !ParseTileKeyBytes(k.substr(8), &key)) continue;
      auto w = wanted.find(key);
      if (w == wanted.end() || found[w->second]) continue;
      found[w->second] = true;
      if (it->value().empty()) continue;
      Result<std::unique_ptr<Tile>> tile = DecodeTile(it->value().ToStringView(), params_.tile_size,
                                                      KeepsPlaneMoments(params_.method));
      if (!tile.ok()) {
        status = Status::DataLoss("history of tile " + TileKeyName(key) + ": " +
                                  tile.status().message());
      } else {
        out[w->second] = std::move(*tile);
      }
    }
    if (status.ok() && !it->status().ok()) status = FromRocks(it->status(), "reading tile history");
  }
  for (size_t i = 0; i < keys.size() && status.ok(); ++i) {
    if (found[i]) continue;
    Result<std::unique_ptr<Tile>> tile = LoadTileAt(keys[i], snapshot);
    if (!tile.ok()) {
      status = tile.status();
    } else {
      out[i] = std::move(*tile);
    }
  }
  db_->db->ReleaseSnapshot(snapshot);
  if (!status.ok()) return status;
  return out;
}

Status TileStore::ApplyCorrection(const LogRecord& correction, std::span<const LogRecord> rewritten,
                                  std::span<const uint64_t> removed) {
  std::lock_guard<std::mutex> lock(checkpoint_mu_);
  if (Status failed = log_->write_failure(); !failed.ok()) {
    return Status::IoError("the store refuses writes since an earlier failure (" +
                           failed.message() + "); TileStore::Resume() once it is fixed");
  }
  if (correction.type != LogRecord::Type::kCorrection ||
      correction.version <= checkpoint_version_.load()) {
    return Status::InvalidArgument("a correction needs a new version above the checkpoint");
  }
  rocksdb::WriteBatch batch;
  batch.Put(db_->log, VersionKeyBytes(correction.version), EncodeLogRecord(correction));
  batch.Merge(db_->meta, kMapVersionKey, U64Bytes(correction.version));
  for (const LogRecord& record : rewritten) {
    batch.Put(db_->log, VersionKeyBytes(record.version), log_->EncodeStored(record));
    if (record.raw_scan && db_->sources != nullptr) {
      batch.Put(db_->sources, VersionKeyBytes(record.version), EncodeRawScan(*record.raw_scan));
    }
  }
  for (uint64_t version : removed) {
    batch.Delete(db_->log, VersionKeyBytes(version));
    if (db_->sources != nullptr) batch.Delete(db_->sources, VersionKeyBytes(version));
  }
  std::vector<uint64_t> bases = Bases();
  std::erase_if(bases,
                [&](uint64_t b) { return b > correction.base_version && b < correction.version; });
  batch.Put(db_->meta, kBasesKey, EncodeVersionList(bases));
  batch.Put(db_->meta, kBasesFloorKey, U64Bytes(correction.version));
  // A removal rewrites nothing: an operator freeing space, admitted below the reserve.
  const uint64_t bytes = batch.GetDataSize();
  if (Status refused = rewritten.empty() ? log_->AdmitFreeingWrite(bytes) : log_->AdmitWrite(bytes);
      !refused.ok()) {
    return refused;
  }
  rocksdb::WriteOptions write;
  write.sync = true;  // acknowledged only once durable, in either durability mode
  if (Status s = FromRocks(db_->db->Write(write, &batch),
                           "writing correction " + std::to_string(correction.version));
      !s.ok()) {
    log_->LatchFailure(s);
    return s;
  }
  log_->NoteAppended(correction.version);
  {
    std::lock_guard<std::mutex> bases_lock(bases_mu_);
    bases_ = std::move(bases);
    bases_floor_ = correction.version;
  }
  if (!removed.empty()) {
    // The removed records' files leave the disk now (an operator may be freeing a full one).
    const auto [first, last] = std::minmax_element(removed.begin(), removed.end());
    CompactVersions(*first, *last);
  }
  return Status::Ok();
}

}  // namespace bgkmap::storage
