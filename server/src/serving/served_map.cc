#include "serving/served_map.h"

#include <algorithm>
#include <boost/asio/post.hpp>
#include <future>
#include <set>
#include <string>

namespace bgkmap {
namespace {

void SortUnique(std::vector<TileKey>* keys) {
  std::sort(keys->begin(), keys->end());
  keys->erase(std::unique(keys->begin(), keys->end()), keys->end());
}

Status CorruptTile(TileKey k) {
  return Status::DataLoss("tile (" + std::to_string(k.x) + ", " + std::to_string(k.y) +
                          ") of the stored map is corrupt: its cells cannot be answered");
}

}  // namespace

ServedMap::ServedMap(std::unique_ptr<TerrainMap> map, Durability& durability,
                     boost::asio::thread_pool& workers, ServedMapOptions options)
    : durability_(durability),
      table_(std::move(map), /*keep_cleared=*/durability.persists(),
             ScanBandOptions{options.scan_bands, options.scan_band_cells,
                             [&workers](std::function<void()> band) {
                               boost::asio::post(workers, std::move(band));
                             }}),
      residency_(table_, durability, durability.persists(), options.tile_memory_limit_bytes,
                 std::move(options.on_over_memory), options.dense_tile_limit_bytes,
                 options.pack_after_idle),
      checkpointer_(durability, durability.persists(), copies_),
      robots_(options.max_robots, options.max_sequence_jump),
      change_log_(durability.recovered_version(), NewHistoryId()),
      scratch_release_(workers, options.worker_threads, options.scratch_idle),
      scheduler_(workers, std::move(options.on_tiles_changed),
                 [this](uint64_t version, const std::vector<TileKey>& tiles,
                        const std::vector<TileBlocks>& blocks) {
                   change_log_.Record(version, tiles, blocks);
                   scratch_release_.Touch();
                 }) {
  scheduler_.Restore(durability.recovered_version());
  robots_.Restore(durability.LoggedRobotSequences());
  // The summary starts from the tiles in memory (recovered) and the store's index of the rest.
  std::vector<TileKey> keys;
  std::vector<TileSummary> summaries;
  std::set<TileKey> resident;
  for (const auto& [key, summary] : table_.SummarizeResident()) {
    keys.push_back(key);
    summaries.push_back(summary);
    resident.insert(key);
  }
  durability.ForEachStored([&](TileKey key, const TileSummary& summary) {
    if (resident.contains(key)) return;
    keys.push_back(key);
    summaries.push_back(summary);
  });
  summary_.Update(keys, summaries);
  // Recovered on a full disk: those tiles are newer than the store until a checkpoint.
  checkpointer_.MarkChanged(durability.DeferredTiles());
}

ServedMap::~ServedMap() { scheduler_.WaitIdle(); }

bool ServedMap::TakeDuplicate(const std::string& robot_id, uint64_t sequence, uint64_t* last) {
  if (!robots_.IsDuplicate(robot_id, sequence, last)) return false;
  robots_.CountDuplicate(robot_id);
  return true;
}

ServedMap::Admission ServedMap::SubmitScan(ScanOrigin origin,
                                           std::shared_ptr<const PreparedScan> scan,
                                           std::function<void(ScanOutcome)> done,
                                           uint64_t* last_sequence) {
  std::lock_guard admission(admission_mu_);
  uint64_t previous = 0;
  const Admission a =
      robots_.Admit(origin.robot_id, origin.sequence, origin.stamp, scan->counts.kept, &previous);
  if (last_sequence != nullptr) *last_sequence = previous;
  if (a != Admission::kAdmitted) return a;
  if (origin.pose) robots_.RecordPose(origin.robot_id, *origin.pose);
  ChangeScheduler::TileChange kind{scan->ChangeableTiles(), scan->read_tiles};
  scheduler_.Submit(std::move(kind), [this, origin = std::move(origin), scan = std::move(scan),
                                      previous, done = std::move(done)](uint64_t version) mutable {
    return RunScan(origin, std::move(scan), previous, version, std::move(done));
  });
  return a;
}

ChangeScheduler::Done ServedMap::RunScan(const ScanOrigin& origin,
                                         std::shared_ptr<const PreparedScan> shared_scan,
                                         uint64_t previous_sequence, uint64_t version,
                                         std::function<void(ScanOutcome)> done) {
  const PreparedScan& scan = *shared_scan;
  ScanOutcome outcome;
  outcome.version = version;
  // The tiles are brought into memory before the scan is journaled: a store that cannot be read
  // refuses the scan like a journal that cannot be written.
  Result<TileResidency::Pins> pins = residency_.PinScan(scan);
  outcome.status = pins.status();
  if (outcome.status.ok()) {
    ChangeRecord record{version, shared_scan, origin.robot_id, origin.sequence, {}, origin.raw};
    outcome.status = durability_.Record(record);
  }
  if (!outcome.status.ok()) {
    // Not in the log, so not in the map: the robot may send it again.
    robots_.Withdraw(origin.robot_id, origin.sequence, previous_sequence, scan.counts.kept);
    return {{}, [done = std::move(done), outcome = std::move(outcome)] { done(outcome); }};
  }
  ScanReport report = table_.ApplyScan(scan, version);
  outcome.changed_tiles = report.changed_tiles;
  summary_.MarkStale(outcome.changed_tiles);
  checkpointer_.MarkChanged(outcome.changed_tiles);
  scans_applied_.fetch_add(1);
  residency_.SignalIfOverLimit();
  return {std::move(report.changed_tiles),
          [done = std::move(done), outcome = std::move(outcome)] { done(outcome); },
          std::move(report.changed_blocks)};
}

void ServedMap::SubmitClear(const CellBox& box, std::function<void(ClearOutcome)> done) {
  scheduler_.Submit(ChangeScheduler::ExclusiveChange{},
                    [this, box, done = std::move(done)](uint64_t version) mutable {
                      return RunClear(box, version, std::move(done));
                    });
}

ChangeScheduler::Done ServedMap::RunClear(const CellBox& box, uint64_t version,
                                          std::function<void(ClearOutcome)> done) {
  ClearOutcome outcome;
  outcome.version = version;
  Result<TileResidency::Pins> pins = TileResidency::Pins();
  if (!box.empty()) {
    pins = residency_.PinRange(geometry().TileOf(box.min), geometry().TileOf(box.max),
                               /*strict=*/false);
  }
  outcome.status = pins.status();
  if (outcome.status.ok()) {
    ChangeRecord record;
    record.version = version;
    record.clear_box = box;
    outcome.status = durability_.Record(record);
  }
  if (outcome.status.ok()) {
    outcome.changed_tiles = table_.ClearBox(box, version);
    summary_.MarkStale(outcome.changed_tiles);
    checkpointer_.MarkChanged(outcome.changed_tiles);
  }
  std::vector<TileKey> tiles = outcome.changed_tiles;
  return {std::move(tiles),
          [done = std::move(done), outcome = std::move(outcome)] { done(outcome); }};
}

void ServedMap::SubmitImport(std::span<const TileKey> keys,
                             std::span<const std::unique_ptr<Tile>> tiles,
                             std::function<void(ImportOutcome)> done) {
  scheduler_.Submit(ChangeScheduler::ExclusiveChange{},
                    [this, keys, tiles, done = std::move(done)](uint64_t version) mutable {
                      return RunImport(keys, tiles, version, std::move(done));
                    });
}

ChangeScheduler::Done ServedMap::RunImport(std::span<const TileKey> keys,
                                           std::span<const std::unique_ptr<Tile>> tiles,
                                           uint64_t version,
                                           std::function<void(ImportOutcome)> done) {
  ImportOutcome outcome{version, Status::Ok()};
  auto finish = [&](std::vector<TileKey> changed) -> ChangeScheduler::Done {
    return {std::move(changed), [done = std::move(done), outcome] { done(outcome); }};
  };
  // Loads the stored tiles first: never add onto a tile that was lost.
  Result<TileResidency::Pins> pins =
      residency_.Pin(std::vector<TileKey>(keys.begin(), keys.end()), /*strict=*/true);
  if (!pins.ok()) {
    outcome.status = pins.status();
    return finish({});
  }
  // Not journaled (an archive can be huge): durable by a checkpoint at its own version, which
  // holds every earlier change too; undone from these copies if that fails.
  std::vector<const Tile*> adding;
  adding.reserve(tiles.size());
  for (const auto& t : tiles) adding.push_back(t.get());
  // Sums that overflow would leave a map answering NaN whose own export is not importable:
  // refused as a whole, before anything is added.
  if (Status s = table_.CheckSumsFinite(keys, adding); !s.ok()) {
    outcome.status = s;
    return finish({});
  }
  const std::vector<std::unique_ptr<Tile>> before = table_.CopyTiles(keys);
  table_.AddTiles(keys, adding, version);
  checkpointer_.MarkChanged(keys);
  summary_.MarkStale(keys);  // (an undone import recounts to what it was)
  durability_.NoteChangeOutsideLog(version);
  if (Status s = checkpointer_.CheckpointAt(version); !s.ok()) {
    table_.ReplaceTiles(keys, before);
    outcome.status = Status::IoError("cannot persist it: " + s.message());
    return finish({});
  }
  residency_.SignalIfOverLimit();
  return finish(std::vector<TileKey>(keys.begin(), keys.end()));
}

void ServedMap::RetireRobot(const std::string& robot_id,
                            std::function<void(Result<RobotStats>)> done) {
  std::lock_guard admission(admission_mu_);  // ordered with the admission of scans
  std::optional<RobotStats> gone = robots_.Retire(robot_id);
  if (!gone) {
    done(Status::FailedPrecondition("robot_id: '" + robot_id + "' is not a known robot"));
    return;
  }
  // At the barrier every scan admitted before the retirement is journaled; those admitted after
  // it journal their robot again, as a new one.
  scheduler_.Submit(ChangeScheduler::Barrier{},
                    [this, robot = std::move(*gone),
                     done = std::move(done)](uint64_t) mutable -> ChangeScheduler::Done {
                      Result<RobotStats> result = robot;
                      if (Status s = durability_.RetireRobot(robot.robot_id); !s.ok()) {
                        robots_.Unretire(robot);
                        result = Status::IoError("cannot persist it: " + s.message());
                      }
                      auto shared = std::make_shared<Result<RobotStats>>(std::move(result));
                      return {{}, [done = std::move(done), shared] { done(std::move(*shared)); }};
                    });
}

void ServedMap::SubmitSnapshot(TileKey min, TileKey max,
                               std::function<void(Result<MapSnapshot>)> done) {
  scheduler_.Submit(
      ChangeScheduler::Barrier{},
      [this, min, max, done = std::move(done)](uint64_t applied) mutable -> ChangeScheduler::Done {
        // The store must hold exactly the map at `applied` before it is read.
        Result<MapSnapshot> snapshot = Status::Ok();
        if (Status s = checkpointer_.CheckpointAt(applied); !s.ok()) {
          snapshot = Status::IoError("cannot checkpoint it first: " + s.message());
        } else if (Result<std::unique_ptr<TilesAtVersion>> tiles =
                       durability_.OpenTileSource(min, max, copies_);
                   !tiles.ok()) {
          snapshot = tiles.status();
        } else {
          snapshot = MapSnapshot{applied, durability_.LoggedRobotSequences(), std::move(*tiles)};
        }
        auto shared = std::make_shared<Result<MapSnapshot>>(std::move(snapshot));
        return {{}, [done = std::move(done), shared] { done(std::move(*shared)); }};
      });
}

Status ServedMap::Checkpoint() {
  std::promise<CapturedCheckpoint> captured;
  std::future<CapturedCheckpoint> ready = captured.get_future();
  scheduler_.Submit(ChangeScheduler::Barrier{}, [this, &captured](uint64_t applied) {
    captured.set_value(checkpointer_.Capture(applied));
    return ChangeScheduler::Done{};
  });
  return checkpointer_.Write(ready.get());
}

Status ServedMap::RefuseCorrupt(TileKey min, TileKey max) const {
  for (TileKey k : durability_.CorruptTiles()) {
    if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) return CorruptTile(k);
  }
  return Status::Ok();
}

Status ServedMap::RefuseCorrupt(std::span<const TileKey> keys) const {
  const std::vector<TileKey> corrupt = durability_.CorruptTiles();  // sorted
  for (TileKey k : keys) {
    if (std::binary_search(corrupt.begin(), corrupt.end(), k)) return CorruptTile(k);
  }
  return Status::Ok();
}

Result<Raster> ServedMap::ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                                     int stride) {
  const TileKey lo = geometry().TileOf(box.min), hi = geometry().TileOf(box.max);
  if (Status s = RefuseCorrupt(lo, hi); !s.ok()) return s;
  TileLockTable::Guard locked = table_.LockRangeShared(lo, hi);
  // Pinned under the tile locks: no scan can add a tile to the range meanwhile.
  Result<TileResidency::Pins> pins = residency_.PinRange(lo, hi, /*strict=*/true);
  if (!pins.ok()) return pins.status();
  return table_.ReadRegion(box, layers, stride);
}

std::vector<TileKey> ServedMap::TilesOf(std::span<const CellIndex> cells) const {
  std::vector<TileKey> keys;
  keys.reserve(cells.size());
  for (CellIndex c : cells) keys.push_back(geometry().TileOf(c));
  SortUnique(&keys);
  return keys;
}

Result<std::vector<CellEstimate>> ServedMap::ReadCells(std::span<const CellIndex> cells) {
  std::vector<TileKey> keys = TilesOf(cells);
  if (Status s = RefuseCorrupt(keys); !s.ok()) return s;
  TileLockTable::Guard locked = table_.LockShared(keys);
  Result<TileResidency::Pins> pins = residency_.Pin(std::move(keys), /*strict=*/true);
  if (!pins.ok()) return pins.status();
  return table_.ReadCells(cells);
}

std::optional<Result<std::vector<CellEstimate>>> ServedMap::TryReadCellsNow(
    std::span<const CellIndex> cells) {
  std::vector<TileKey> keys = TilesOf(cells);
  if (Status s = RefuseCorrupt(keys); !s.ok()) return Result<std::vector<CellEstimate>>(s);
  std::optional<TileLockTable::Guard> locked = table_.TryLockShared(keys);
  if (!locked) return std::nullopt;  // a change holds one of them
  std::optional<TileResidency::Pins> pins = residency_.TryPinInMemory(std::move(keys));
  if (!pins) return std::nullopt;  // a tile to load, or eviction at work
  return Result<std::vector<CellEstimate>>(table_.ReadCells(cells));
}

Result<TileContent> ServedMap::ReadTile(TileKey key, const std::vector<Layer>& layers) {
  const TileKey one[] = {key};
  if (Status s = RefuseCorrupt(one); !s.ok()) return s;
  TileLockTable::Guard locked = table_.LockShared(one);
  Result<TileResidency::Pins> pins = residency_.Pin({key}, /*strict=*/true);
  if (!pins.ok()) return pins.status();
  auto [raster, version] = table_.ReadTile(key, layers);
  return TileContent{std::move(raster), version};
}

MapSummary ServedMap::Summary() {
  return summary_.Get([this](std::span<const TileKey> keys) {
    // Under shared tile locks: no change is half applied to a tile being counted. A tile not in
    // memory is clean (only clean tiles are evicted), so the store's summary of it is current.
    TileLockTable::Guard locked = table_.LockShared(keys);
    const std::vector<std::optional<TileSummary>> resident = table_.SummarizeIfResident(keys);
    std::vector<TileSummary> out;
    out.reserve(keys.size());
    for (size_t i = 0; i < keys.size(); ++i) {
      out.push_back(resident[i] ? *resident[i]
                                : durability_.StoredSummary(keys[i]).value_or(TileSummary{}));
    }
    return out;
  });
}

std::vector<TileKey> ServedMap::ListTiles(TileKey min, TileKey max) const {
  return residency_.KeysIn(min, max);
}

Result<std::vector<ChangedTile>> ServedMap::TilesChangedSince(TileKey min, TileKey max,
                                                              uint64_t since) {
  std::optional<std::vector<ChangedTile>> keys = change_log_.ChangedSince(min, max, since);
  if (!keys) {
    return Status::FailedPrecondition(
        "since_version " + std::to_string(since) + " is older than map version " +
        std::to_string(change_log_.floor()) +
        ", where this server started: changes before it are not recorded per tile");
  }
  return std::move(*keys);
}

std::unique_ptr<TerrainMap> ServedMap::Snapshot() const {
  std::set<TileKey> resident;
  std::unique_ptr<TerrainMap> out = table_.CopyResident(applied_version(), &resident);
  durability_.ForEachStored([&](TileKey k, const TileSummary&) {
    if (resident.contains(k)) return;  // (a cleared tile in memory is newer than its stored copy)
    Result<std::unique_ptr<Tile>> tile = durability_.Load(k);
    if (tile.ok() && *tile != nullptr) out->SetTile(k, **tile);
  });
  return out;
}

}  // namespace bgkmap
