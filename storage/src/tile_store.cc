#include "bgkmap/storage/tile_store.h"

#include <rocksdb/convenience.h>
#include <rocksdb/write_batch.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <map>
#include <optional>

#include "bgkmap/storage/tile_codec.h"
#include "byte_coding.h"
#include "store_db.h"
#include "store_keys.h"

namespace bgkmap::storage {
namespace {

// Index value: varints version, known cells, encoded bytes, then the known cells' tile-local
// bounding box (min x, min y, max x, max y). Entries written before the box was added end after
// the bytes; their box is the whole tile.
std::string EncodeTileInfo(const Tile& tile, uint32_t bytes) {
  std::string out;
  ByteWriter w(&out);
  w.PutVarint(tile.version());
  const Tile::KnownCells known = tile.Known();
  w.PutVarint(static_cast<uint64_t>(known.count));
  w.PutVarint(bytes);
  const CellBox& box = known.local_box;
  for (int v : {box.min.x, box.min.y, box.max.x, box.max.y}) {
    w.PutVarint(static_cast<uint64_t>(v));
  }
  return out;
}

bool DecodeTileInfo(std::string_view key, std::string_view value, int tile_size,
                    StoredTileInfo* info) {
  ByteReader r(value);
  uint64_t version, known, bytes;
  if (!ParseTileKeyBytes(key, &info->key) || !r.GetVarint(&version) || !r.GetVarint(&known) ||
      !r.GetVarint(&bytes)) {
    return false;
  }
  info->version = version;
  info->known_cells = static_cast<uint32_t>(known);
  info->encoded_bytes = static_cast<uint32_t>(bytes);
  CellBox local{{0, 0}, {tile_size - 1, tile_size - 1}};
  if (r.remaining() > 0) {
    uint64_t v[4];
    for (uint64_t& x : v) {
      if (!r.GetVarint(&x) || x >= static_cast<uint64_t>(tile_size)) return false;
    }
    local = {{static_cast<int>(v[0]), static_cast<int>(v[1])},
             {static_cast<int>(v[2]), static_cast<int>(v[3])}};
  }
  // (The resolution plays no part in cell arithmetic.)
  info->known_box = GridGeometry(1.0, tile_size).LocalToMap(info->key, local);
  return true;
}

// The whole meta family (a few dozen keys), merges resolved.
Result<std::map<std::string, std::string, std::less<>>> ReadMeta(StoreDb& db) {
  std::map<std::string, std::string, std::less<>> meta;
  std::unique_ptr<rocksdb::Iterator> it(db.db->NewIterator(rocksdb::ReadOptions(), db.meta));
  for (it->SeekToFirst(); it->Valid(); it->Next())
    meta.emplace(it->key().ToString(), it->value().ToString());
  if (!it->status().ok()) return FromRocks(it->status(), "reading the map metadata");
  return meta;
}

Status PutParams(rocksdb::WriteBatch& batch, StoreDb& db, const MapParams& params) {
  for (const auto& [key, value] : ParamsToKeyValues(params)) {
    rocksdb::Status s = batch.Put(db.meta, std::string(kParamPrefix) + key, value);
    if (!s.ok()) return FromRocks(s, "writing the map parameters");
  }
  return Status::Ok();
}

Status PutGeoreference(rocksdb::WriteBatch& batch, StoreDb& db, const Georeference& g) {
  for (const auto& [key, value] : GeoreferenceToKeyValues(g)) {
    rocksdb::Status s = batch.Put(db.meta, std::string(kGeoreferencePrefix) + key, value);
    if (!s.ok()) return FromRocks(s, "writing the map georeference");
  }
  return Status::Ok();
}

Result<uint64_t> MetaU64(const std::map<std::string, std::string, std::less<>>& meta,
                         std::string_view key) {
  auto it = meta.find(key);
  if (it == meta.end()) return uint64_t{0};
  uint64_t v;
  if (!ParseU64Bytes(it->second, &v)) {
    return Status::DataLoss("map metadata " + std::string(key) + " is malformed");
  }
  return v;
}

using MetaMap = std::map<std::string, std::string, std::less<>>;

// The values under `prefix`, keyed without it.
MetaMap WithPrefix(const MetaMap& meta, std::string_view prefix) {
  MetaMap out;
  for (const auto& [key, value] : meta) {
    if (key.starts_with(prefix)) out.emplace(key.substr(prefix.size()), value);
  }
  return out;
}

// Whether a store in `dir` opens read-only: it exists on a disk below the free-space reserve
// (serve what is stored; write nothing, not even RocksDB's own files). IoError if there is no
// store yet and no room to make one.
Result<bool> OpensReadOnly(const std::string& dir, FreeSpaceGuard& guard) {
  std::error_code ec;
  if (!guard.enabled() || !std::filesystem::is_directory(dir, ec)) return false;
  Status space = guard.Check();
  if (space.ok()) return false;
  if (!std::filesystem::exists(dir + "/CURRENT", ec)) {
    return Status::IoError("cannot create a map store in " + dir + ": " + space.message());
  }
  return true;
}

// A new store's metadata, into `batch`.
Status InitMeta(const StoreOptions& options, const MapParams& params, StoreDb& db,
                rocksdb::WriteBatch& batch) {
  batch.Put(db.meta, kFormatKey, std::to_string(kStoreFormat));
  batch.Put(db.meta, kCheckpointVersionKey, U64Bytes(0));
  // A new store's log is complete from the start: the empty map at version 0 is a base.
  if (options.retention.enabled()) batch.Put(db.meta, kBasesKey, EncodeVersionList({0}));
  return PutParams(batch, db, params);
}

// An existing store's metadata, checked against what the opener asks: a format this build reads
// (an older one is upgraded in place), a compatible georeference, and `params` (if given)
// compatible with the stored ones, which they then replace. The parameters and georeference in
// effect go to `effective` and `stored_georeference`; updates go to `batch`.
Status ReconcileMeta(const std::string& dir, const MetaMap& meta, const MapParams* params,
                     const Georeference& georeference, StoreDb& db, rocksdb::WriteBatch& batch,
                     MapParams* effective, Georeference* stored_georeference) {
  Result<Georeference> stored_geo =
      GeoreferenceFromKeyValues(WithPrefix(meta, kGeoreferencePrefix));
  if (!stored_geo.ok()) return stored_geo.status();
  if (Status s = CheckGeoreferenceCompatible(*stored_geo, georeference); !s.ok()) {
    return Status::FailedPrecondition(dir + ": " + s.message());
  }
  *stored_georeference = *stored_geo;
  uint32_t stored_format = 0;
  const std::string& text = meta.find(kFormatKey)->second;
  if (std::from_chars(text.data(), text.data() + text.size(), stored_format).ec != std::errc()) {
    return Status::DataLoss("store format marker is malformed: " + text);
  }
  if (stored_format > kStoreFormat) {
    return Status::FailedPrecondition("the store in " + dir + " has format " + text +
                                      ", newer than this build reads (" +
                                      std::to_string(kStoreFormat) + ")");
  }
  // An older store upgrades in place: it is read as it is and written from now on in the
  // current formats, which an older build then refuses by this marker.
  if (stored_format < kStoreFormat) batch.Put(db.meta, kFormatKey, std::to_string(kStoreFormat));
  Result<MapParams> stored = ParamsFromKeyValues(WithPrefix(meta, kParamPrefix));
  if (!stored.ok()) return stored.status();
  *effective = *stored;
  if (params == nullptr) return Status::Ok();
  if (Status s = CheckParamsCompatible(*stored, *params); !s.ok()) {
    return Status::FailedPrecondition(dir + ": " + s.message());
  }
  *effective = *params;
  return PutParams(batch, db, *effective);
}

// Puts each tile's coding and index entry into `batch`, and deletes those gone or all zero.
Status AddTiles(const StoreDb& db, int tile_size, const TileEncodeOptions& encoding,
                std::span<const TileUpdate> tiles, rocksdb::WriteBatch* batch, uint64_t* written,
                uint64_t* deleted) {
  for (const TileUpdate& update : tiles) {
    const std::string key = TileKeyBytes(update.key);
    // The checks and the coding read dense arrays: unpack a packed copy once, not in each.
    std::optional<Tile> unpacked;
    if (update.tile != nullptr && update.tile->is_packed()) {
      unpacked.emplace(*update.tile);
      unpacked->Unpack();
    }
    const Tile* tile = unpacked ? &*unpacked : update.tile;
    if (tile == nullptr || IsZeroTile(*tile)) {
      batch->Delete(db.tiles, key);
      batch->Delete(db.tile_index, key);
      ++*deleted;
      continue;
    }
    if (tile->tile_size() != tile_size) {
      return Status::InvalidArgument("tile " + TileKeyName(update.key) + " is " +
                                     std::to_string(tile->tile_size()) +
                                     " cells wide, the map's are " + std::to_string(tile_size));
    }
    const std::string value = EncodeTile(*tile, encoding);
    batch->Put(db.tiles, key, value);
    batch->Put(db.tile_index, key, EncodeTileInfo(*tile, static_cast<uint32_t>(value.size())));
    ++*written;
  }
  return Status::Ok();
}

}  // namespace

TileStore::TileStore(std::string dir, const StoreOptions& options, const MapParams& params,
                     std::unique_ptr<StoreDb> db)
    : dir_(std::move(dir)), options_(options), params_(params), db_(std::move(db)) {}

TileStore::~TileStore() {
  log_.reset();  // stops the syncer and syncs before the database closes
  db_.reset();
}

Result<std::unique_ptr<TileStore>> TileStore::Open(const std::string& dir,
                                                   const StoreOptions& options,
                                                   const MapParams& params,
                                                   const Georeference& georeference) {
  if (Status s = params.Validate(); !s.ok()) return s;
  return OpenImpl(dir, options, &params, georeference);
}

Result<std::unique_ptr<TileStore>> TileStore::OpenExisting(const std::string& dir,
                                                           const StoreOptions& options) {
  StoreOptions existing = options;
  existing.create_if_missing = false;
  return OpenImpl(dir, existing, nullptr, Georeference{});
}

Result<std::unique_ptr<TileStore>> TileStore::OpenImpl(const std::string& dir,
                                                       const StoreOptions& options,
                                                       const MapParams* params,
                                                       const Georeference& georeference) {
  auto guard = std::make_unique<FreeSpaceGuard>(dir, options.free_space);
  Result<bool> read_only = OpensReadOnly(dir, *guard);
  if (!read_only.ok()) return read_only.status();
  Result<std::unique_ptr<StoreDb>> db = StoreDb::Open(dir, options, *read_only);
  if (!db.ok()) return db.status();
  StoreDb& sdb = **db;
  Result<MetaMap> meta = ReadMeta(sdb);
  if (!meta.ok()) return meta.status();

  MapParams effective;
  Georeference stored_georeference;
  rocksdb::WriteBatch batch;
  if (meta->find(kFormatKey) == meta->end()) {
    if (params == nullptr) return Status::FailedPrecondition("no map store in " + dir);
    effective = *params;
    if (Status s = InitMeta(options, effective, sdb, batch); !s.ok()) return s;
  } else if (Status s = ReconcileMeta(dir, *meta, params, georeference, sdb, batch, &effective,
                                      &stored_georeference);
             !s.ok()) {
    return s;
  }
  // The first georeference a map is given is kept (a new store, or one written before).
  if (stored_georeference.empty() && !georeference.empty()) {
    if (Status s = PutGeoreference(batch, sdb, georeference); !s.ok()) return s;
    stored_georeference = georeference;
  }
  if (batch.Count() > 0 &&
      !*read_only) {  // (read-only: the parameters are updated at the next open)
    rocksdb::WriteOptions write;
    write.sync = true;
    if (Status s = FromRocks(sdb.db->Write(write, &batch), "writing the map metadata"); !s.ok()) {
      return s;
    }
  }

  std::unique_ptr<TileStore> store(new TileStore(dir, options, effective, nullptr));
  store->guard_ = std::move(guard);
  store->read_only_.store(*read_only);
  store->georeference_ = std::move(stored_georeference);
  if (Status s = store->Attach(std::move(*db)); !s.ok()) return s;
  return store;
}

Status TileStore::Attach(std::unique_ptr<StoreDb> db) {
  Result<std::map<std::string, std::string, std::less<>>> meta = ReadMeta(*db);
  if (!meta.ok()) return meta.status();
  Result<uint64_t> checkpoint = MetaU64(*meta, kCheckpointVersionKey);
  Result<uint64_t> map_version = MetaU64(*meta, kMapVersionKey);
  if (!checkpoint.ok()) return checkpoint.status();
  if (!map_version.ok()) return map_version.status();
  std::map<std::string, uint64_t> robots;
  for (const auto& [key, value] : *meta) {
    if (!key.starts_with(kRobotPrefix)) continue;
    uint64_t sequence;
    if (!ParseU64Bytes(value, &sequence)) {
      return Status::DataLoss("map metadata " + key + " is malformed");
    }
    robots.emplace(key.substr(kRobotPrefix.size()), sequence);
  }
  std::vector<uint64_t> bases;
  if (auto it = meta->find(kBasesKey);
      it != meta->end() && !DecodeVersionList(it->second, &bases)) {
    return Status::DataLoss("map metadata " + std::string(kBasesKey) + " is malformed");
  }
  uint64_t floor = 0;
  if (auto it = meta->find(kBasesFloorKey);
      it != meta->end() && !ParseU64Bytes(it->second, &floor)) {
    return Status::DataLoss("map metadata " + std::string(kBasesFloorKey) + " is malformed");
  }
  {
    std::lock_guard<std::mutex> lock(bases_mu_);
    bases_ = std::move(bases);
    bases_floor_ = floor;
  }
  // The memory tables go to disk at their next flush, whatever the robots are told.
  guard_->SetPendingBytes([buffers = db->write_buffers] { return buffers->memory_usage(); });
  db_ = std::move(db);
  checkpoint_version_.store(*checkpoint);
  log_.reset(new ScanLog(db_.get(), options_, params_, std::max(*map_version, *checkpoint),
                         std::move(robots), *checkpoint, guard_.get(), read_only_.load()));
  return Status::Ok();
}

uint64_t TileStore::map_version() const {
  return std::max(checkpoint_version_.load(), log_->last_version());
}

Georeference TileStore::georeference() const {
  std::lock_guard<std::mutex> lock(georeference_mu_);
  return georeference_;
}

Status TileStore::AdoptGeoreference(const Georeference& georeference) {
  std::lock_guard<std::mutex> lock(georeference_mu_);
  if (Status s = CheckGeoreferenceCompatible(georeference_, georeference); !s.ok()) return s;
  if (georeference.empty() || georeference == georeference_) return Status::Ok();
  if (Status failed = log_->write_failure(); !failed.ok()) {
    return Status::IoError("the store refuses writes since an earlier failure (" +
                           failed.message() + "); TileStore::Resume() once it is fixed");
  }
  rocksdb::WriteBatch batch;
  if (Status s = PutGeoreference(batch, *db_, georeference); !s.ok()) return s;
  if (Status refused = log_->AdmitWrite(batch.GetDataSize()); !refused.ok()) return refused;
  rocksdb::WriteOptions write;
  write.sync = true;
  if (Status s = FromRocks(db_->db->Write(write, &batch), "writing the map georeference");
      !s.ok()) {
    log_->LatchFailure(s);  // every later write is refused until Resume()
    return s;
  }
  georeference_ = georeference;
  return Status::Ok();
}

MapMetadata TileStore::Metadata() const {
  MapMetadata m;
  m.params = params_;
  m.georeference = georeference();
  m.checkpoint_version = checkpoint_version();
  m.map_version = map_version();
  m.robot_sequences = log_->RobotSequences();
  return m;
}

void TileStore::MarkCorrupt(TileKey key) const {
  std::lock_guard<std::mutex> lock(corrupt_mu_);
  if (corrupt_.insert(key).second) corrupt_found_.fetch_add(1);
}

Result<std::unique_ptr<Tile>> TileStore::LoadTile(TileKey key) const {
  return LoadTileAt(key, nullptr);
}

Result<std::unique_ptr<Tile>> TileStore::LoadTileAt(TileKey key,
                                                    const rocksdb::Snapshot* snapshot) const {
  rocksdb::PinnableSlice value;
  rocksdb::ReadOptions read;
  read.verify_checksums = true;
  read.snapshot = snapshot;
  const rocksdb::Status s = db_->db->Get(read, db_->tiles, TileKeyBytes(key), &value);
  if (s.IsNotFound()) return std::unique_ptr<Tile>();
  if (!s.ok()) {
    if (s.IsCorruption() && snapshot == nullptr) MarkCorrupt(key);
    return FromRocks(s, "reading tile " + TileKeyName(key));
  }
  Result<std::unique_ptr<Tile>> tile =
      DecodeTile(value.ToStringView(), params_.tile_size, KeepsPlaneMoments(params_.method));
  if (!tile.ok()) {
    if (tile.status().code() == Status::Code::kDataLoss && snapshot == nullptr) MarkCorrupt(key);
    return Status(
        tile.status().code() == Status::Code::kDataLoss
            ? Status::DataLoss("tile " + TileKeyName(key) + ": " + tile.status().message())
            : tile.status());
  }
  tiles_loaded_.fetch_add(1);
  return tile;
}

Status TileStore::Checkpoint(uint64_t version, std::span<const TileUpdate> tiles,
                             bool forget_earlier_bases) {
  uint64_t dropped_through = 0;
  {
    std::lock_guard<std::mutex> lock(checkpoint_mu_);
    Status s = WriteCheckpoint(version, tiles, forget_earlier_bases, &dropped_through);
    if (!s.ok()) return s;
  }
  // Outside the lock: appends and the next checkpoint need not wait for the compaction.
  if (dropped_through > 0) ReclaimDropped(dropped_through);
  // Short of space: the tiles it deleted (an operator's clear) leave the disk now too.
  if (guard_->enabled() && guard_->free_bytes() < guard_->reserve_bytes()) {
    ReclaimDeletedTiles(tiles);
  }
  return Status::Ok();
}

void TileStore::ReclaimDeletedTiles(std::span<const TileUpdate> tiles) {
  std::string first, last;
  for (const TileUpdate& update : tiles) {
    if (update.tile != nullptr && !IsZeroTile(*update.tile)) continue;
    const std::string key = TileKeyBytes(update.key);
    if (first.empty() || key < first) first = key;
    if (last.empty() || key > last) last = key;
  }
  if (first.empty()) return;
  const rocksdb::Slice from(first), to(last);
  rocksdb::CompactRangeOptions compact;
  compact.exclusive_manual_compaction = false;
  for (rocksdb::ColumnFamilyHandle* family : {db_->tiles, db_->tile_index}) {
    if (!db_->db->CompactRange(compact, family, &from, &to).ok()) reclaim_errors_.fetch_add(1);
  }
  reclaims_.fetch_add(1);
}

Status TileStore::WriteCheckpoint(uint64_t version, std::span<const TileUpdate> tiles,
                                  bool forget_earlier_bases, uint64_t* dropped_through) {
  if (Status failed = log_->write_failure(); !failed.ok()) {
    // RocksDB must not write through a log writer that has failed (7.8 asserts): refuse, like
    // an append, until Resume().
    checkpoint_errors_.fetch_add(1);
    return Status::IoError("the store refuses writes since an earlier failure (" +
                           failed.message() + "); TileStore::Resume() once it is fixed");
  }
  if (version < checkpoint_version_.load()) {
    return Status::InvalidArgument("checkpoint version " + std::to_string(version) +
                                   " is below the last checkpoint (" +
                                   std::to_string(checkpoint_version_.load()) + ")");
  }
  rocksdb::WriteBatch batch;
  // First, so that the history reads the tiles as they were before this checkpoint.
  const uint64_t written_before = log_->written_bytes();
  Result<std::vector<uint64_t>> bases =
      AddRetention(&batch, version, tiles, forget_earlier_bases, dropped_through);
  if (!bases.ok()) {
    checkpoint_errors_.fetch_add(1);
    return bases.status();
  }
  uint64_t written = 0, deleted = 0;
  if (Status s = AddTiles(*db_, params_.tile_size, options_.tile_encoding, tiles, &batch, &written,
                          &deleted);
      !s.ok()) {
    return s;
  }
  batch.Put(db_->meta, kCheckpointVersionKey, U64Bytes(version));
  batch.Merge(db_->meta, kMapVersionKey, U64Bytes(version));
  // Refused before RocksDB writes a byte: it must never meet a full disk (free_space.h). A
  // small one (a clear's deletions, the rest once robots were refused) truncates more log than
  // it writes: it may use the upper half of the reserve, so an operator can free a full disk.
  const uint64_t bytes = batch.GetDataSize();
  if (Status refused = bytes <= guard_->reserve_bytes() / 4 ? log_->AdmitFreeingWrite(bytes)
                                                            : log_->AdmitWrite(bytes);
      !refused.ok()) {
    return refused;
  }
  rocksdb::WriteOptions write;
  write.sync = true;  // rare and large: always durable before it counts
  if (Status s =
          FromRocks(db_->db->Write(write, &batch), "writing checkpoint " + std::to_string(version));
      !s.ok()) {
    checkpoint_errors_.fetch_add(1);
    log_->LatchFailure(s);  // every later write is refused until Resume()
    return s;
  }
  checkpoint_version_.store(version);
  log_->OnCheckpoint(version, written_before);
  {
    std::lock_guard<std::mutex> bases_lock(bases_mu_);
    bases_ = std::move(*bases);
  }
  tiles_written_.fetch_add(written);
  tiles_deleted_.fetch_add(deleted);
  checkpoints_.fetch_add(1);
  {
    // A rewritten tile is whole again.
    std::lock_guard<std::mutex> corrupt_lock(corrupt_mu_);
    for (const TileUpdate& update : tiles) corrupt_.erase(update.key);
  }
  return Status::Ok();
}

Result<std::vector<StoredTileInfo>> TileStore::ListTiles() const {
  return ListTiles({INT32_MIN, INT32_MIN}, {INT32_MAX, INT32_MAX});
}

Result<std::vector<StoredTileInfo>> TileStore::ListTiles(TileKey min, TileKey max) const {
  return ListTilesAt(min, max, nullptr);
}

Result<std::vector<StoredTileInfo>> TileStore::ListTilesAt(
    TileKey min, TileKey max, const rocksdb::Snapshot* snapshot) const {
  std::vector<StoredTileInfo> out;
  if (min.x > max.x || min.y > max.y) return out;
  rocksdb::ReadOptions read;
  read.snapshot = snapshot;
  std::unique_ptr<rocksdb::Iterator> it(db_->db->NewIterator(read, db_->tile_index));
  const std::string end = TileKeyBytes(max);
  for (it->Seek(TileKeyBytes(min)); it->Valid() && it->key().ToStringView() <= end; it->Next()) {
    StoredTileInfo info;
    if (!DecodeTileInfo(it->key().ToStringView(), it->value().ToStringView(), params_.tile_size,
                        &info)) {
      return Status::DataLoss("tile index entry is malformed");
    }
    if (info.key.y < min.y || info.key.y > max.y) continue;
    out.push_back(info);
  }
  if (!it->status().ok()) return FromRocks(it->status(), "listing tiles");
  return out;
}

std::vector<TileKey> TileStore::CorruptTiles() const {
  std::lock_guard<std::mutex> lock(corrupt_mu_);
  return {corrupt_.begin(), corrupt_.end()};
}

Status TileStore::Flush() {
  rocksdb::FlushOptions flush;
  flush.wait = true;
  std::vector<rocksdb::ColumnFamilyHandle*> families = {db_->meta, db_->tiles, db_->tile_index,
                                                        db_->log};
  return FromRocks(db_->db->Flush(flush, families), "flushing the store");
}

void TileStore::ReclaimDropped(uint64_t through) {
  // A range delete only hides the records: RocksDB 7.8 left their SST files on disk for hours
  // (issue 25). The version-keyed families are never compacted on their own (store_db.cc), so
  // their files hold runs of consecutive versions: those wholly dropped are deleted, writing
  // nothing, and only the file that straddles the horizon is compacted, writing what it keeps.
  // Deleting files ignores snapshots: safe because nothing reads below the horizon (replay and
  // corrections start at a retained checkpoint, which the checkpoint just written keeps).
  const std::string begin = VersionKeyBytes(0), end = VersionKeyBytes(through + 1);
  const rocksdb::Slice from(begin), limit(end);
  const rocksdb::RangePtr dropped(&from, &limit);
  for (rocksdb::ColumnFamilyHandle* family : {db_->log, db_->sources, db_->history}) {
    if (family == nullptr) continue;
    if (!rocksdb::DeleteFilesInRanges(db_->db.get(), family, &dropped, 1, /*include_end=*/false)
             .ok()) {
      reclaim_errors_.fetch_add(1);
    }
  }
  CompactVersions(0, through);
}

void TileStore::CompactVersions(uint64_t first, uint64_t last) {
  const std::string begin = VersionKeyBytes(first), end = VersionKeyBytes(last + 1);
  const rocksdb::Slice from(begin), limit(end);
  rocksdb::CompactRangeOptions compact;
  compact.exclusive_manual_compaction = false;
  for (rocksdb::ColumnFamilyHandle* family : {db_->log, db_->sources, db_->history}) {
    if (family == nullptr) continue;
    if (!db_->db->CompactRange(compact, family, first == 0 ? nullptr : &from, &limit).ok()) {
      reclaim_errors_.fetch_add(1);  // the space comes back at a later checkpoint
    }
  }
  reclaims_.fetch_add(1);
}

Status TileStore::Compact() {
  if (Status s = Flush(); !s.ok()) return s;
  rocksdb::CompactRangeOptions compact;
  compact.bottommost_level_compaction = rocksdb::BottommostLevelCompaction::kForce;
  for (rocksdb::ColumnFamilyHandle* family : db_->handles) {
    if (Status s = FromRocks(db_->db->CompactRange(compact, family, nullptr, nullptr),
                             "compacting the store");
        !s.ok()) {
      return s;
    }
  }
  return Status::Ok();
}

Status TileStore::Resume() {
  const bool read_only = read_only_.load();
  if (!read_only && log_->write_failure().ok()) return Status::Ok();
  // Reopening (or RocksDB's own resume, which retries its flush) writes: not onto a disk that is
  // still below the reserve.
  if (Status space = guard_->Check(); !space.ok()) return space;
  if (!read_only && db_->db->Resume().ok()) {
    log_->ClearFailure();
    return Status::Ok();
  }
  // RocksDB cannot resume in place after a failed log write: reopen the database, which
  // replays its log up to the last complete record. Every acknowledged record is in it.
  if (const int open = open_snapshots_.load(); open > 0) {
    return Status::IoError("cannot reopen the store while " + std::to_string(open) +
                           " snapshot(s) of it are open (an export is running); retry later");
  }
  log_.reset();
  db_.reset();
  Result<std::unique_ptr<StoreDb>> db = StoreDb::Open(dir_, options_);
  if (!db.ok()) {
    // Keep serving what is stored (as before, read-only or refusing writes) and retry later.
    const Status failed = db.status();
    db = StoreDb::Open(dir_, options_, /*read_only=*/true);
    if (!db.ok()) return failed;
    read_only_.store(true);
    if (Status s = Attach(std::move(*db)); !s.ok()) return s;
    return failed;
  }
  read_only_.store(false);
  return Attach(std::move(*db));
}

StoreCounters TileStore::counters() const {
  StoreCounters c;
  c.tiles_loaded = tiles_loaded_.load();
  c.tiles_written = tiles_written_.load();
  c.tiles_deleted = tiles_deleted_.load();
  c.checkpoints = checkpoints_.load();
  c.corrupt_tiles = corrupt_found_.load();
  c.corrupt_log_records = log_->corrupt_records();
  c.log_records_appended = log_->records_appended();
  c.log_bytes_appended = log_->bytes_appended();
  c.write_errors = log_->append_errors() + checkpoint_errors_.load();
  c.writes_refused_for_space = log_->space_refusals();
  c.reclaims = reclaims_.load();
  c.reclaim_errors = reclaim_errors_.load();
  return c;
}

DiskUsage TileStore::Usage() const {
  DiskUsage usage;
  db_->db->GetIntProperty(db_->tiles, "rocksdb.total-sst-files-size", &usage.tile_bytes);
  db_->db->GetIntProperty(db_->log, "rocksdb.total-sst-files-size", &usage.log_bytes);
  if (db_->sources != nullptr) {
    db_->db->GetIntProperty(db_->sources, "rocksdb.total-sst-files-size", &usage.sources_bytes);
  }
  if (db_->history != nullptr) {
    db_->db->GetIntProperty(db_->history, "rocksdb.total-sst-files-size", &usage.history_bytes);
  }
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    if (!entry.is_regular_file(ec)) continue;
    const uint64_t size = entry.file_size(ec);
    usage.total_bytes += size;
    if (entry.path().extension() == ".log") usage.wal_bytes += size;
  }
  return usage;
}

}  // namespace bgkmap::storage
