#include "bgkmap/storage/reintegration.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <set>

#include "bgkmap/core/terrain_map.h"

namespace bgkmap::storage {
namespace {

struct HistoryEntry {
  uint64_t version = 0;
  std::shared_ptr<const PreparedScan> scan;  // null: a clear
  // The record as logged when its cells are kept in its raw scan: they are prepared again only
  // if it is replayed (the plan reads its tile lists alone).
  std::optional<LogRecord> cells_in_source;
  CellBox clear_box;
  bool revised = false;
  bool replay = false;
};

bool AnyIn(const std::vector<TileKey>& keys, const std::set<TileKey>& set) {
  return std::any_of(keys.begin(), keys.end(), [&](TileKey k) { return set.contains(k); });
}

bool AnyInRange(TileKey lo, TileKey hi, const std::set<TileKey>& set) {
  return std::any_of(set.begin(), set.end(), [&](TileKey k) {
    return k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y;
  });
}

Status ReadHistory(const TileStore& store, const ReintegrationRequest& request,
                   std::vector<HistoryEntry>* entries) {
  const std::set<uint64_t> in_log(request.revised_in_log.begin(), request.revised_in_log.end());
  std::set<uint64_t> replaced_seen;
  const Status stop = Status::OutOfRange("end of the history");
  Status walked = store.log().ForEach(
      request.base,
      [&](uint64_t version, Result<LogRecord> record) -> Status {
        if (version >= request.end) return stop;
        if (!record.ok()) return record.status();
        if (record->type == LogRecord::Type::kCorrection) return Status::Ok();  // see header
        HistoryEntry e;
        e.version = version;
        if (record->type == LogRecord::Type::kClear) {
          e.clear_box = record->clear_box;
          entries->push_back(std::move(e));
          return Status::Ok();
        }
        e.scan = record->scan;
        if (auto r = request.replacements.find(version); r != request.replacements.end()) {
          replaced_seen.insert(version);
          if (r->second == nullptr) return Status::Ok();  // removed
          e.scan = r->second;
          e.revised = true;
        } else if (record->cells_in_source) {
          e.cells_in_source = std::move(*record);
        }
        e.revised = e.revised || in_log.contains(version);
        entries->push_back(std::move(e));
        return Status::Ok();
      },
      ScanLog::LogRead::kHeaders);
  if (!walked.ok() && walked.message() != stop.message()) return walked;
  for (const auto& [version, scan] : request.replacements) {
    if (!replaced_seen.contains(version)) {
      return Status::InvalidArgument("version " + std::to_string(version) +
                                     " is not a scan record after checkpoint " +
                                     std::to_string(request.base));
    }
  }
  return Status::Ok();
}

// Replays the history's chosen records onto the needed tiles as they were at `base`, and puts
// the affected tiles' results in `out->tiles`. A record whose cells are kept in its raw scan is
// prepared again here, only if it is replayed.
Status Replay(const TileStore& store, uint64_t base_version,
              const std::vector<HistoryEntry>& history, Reintegration* out) {
  Result<std::vector<std::unique_ptr<Tile>>> base = store.LoadTilesAt(base_version, out->needed);
  if (!base.ok()) return base.status();
  Result<std::unique_ptr<TerrainMap>> scratch = TerrainMap::Create(store.params());
  if (!scratch.ok()) return scratch.status();
  TerrainMap& map = **scratch;
  for (size_t i = 0; i < out->needed.size(); ++i) {
    if ((*base)[i] != nullptr) map.SetTile(out->needed[i], *(*base)[i]);
  }
  map.set_version(base_version);
  for (const HistoryEntry& e : history) {
    if (!e.replay) continue;
    if (e.scan == nullptr) {
      map.ClearBox(e.clear_box, e.version);
    } else {
      std::shared_ptr<const PreparedScan> scan = e.scan;
      if (e.cells_in_source) {
        Result<std::shared_ptr<const PreparedScan>> whole =
            store.log().LoadCells(e.version, *e.cells_in_source);
        if (!whole.ok()) return whole.status();
        scan = std::move(whole).value();
      }
      const TileWindow window = map.MakeWindow(*scan);
      map.Integrate(*scan, window, e.version);
    }
    map.set_version(e.version);
  }
  out->tiles.reserve(out->affected.size());
  for (TileKey k : out->affected) {
    const Tile* t = map.FindTile(k);
    out->tiles.push_back(t == nullptr ? nullptr : std::make_unique<Tile>(*t));
  }
  return Status::Ok();
}

}  // namespace

void AffectedTiles::Add(const PreparedScan& scan, bool revised) {
  std::vector<TileKey> inputs = scan.ChangeableTiles();
  if (revised || AnyIn(inputs, tiles_) || AnyIn(scan.read_tiles, tiles_)) {
    tiles_.insert(inputs.begin(), inputs.end());
  }
}

Result<Reintegration> Reintegrate(const TileStore& store, const ReintegrationRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<uint64_t> bases = store.Bases();
  if (!std::binary_search(bases.begin(), bases.end(), request.base)) {
    return Status::InvalidArgument("version " + std::to_string(request.base) +
                                   " is not a retained checkpoint");
  }
  std::vector<HistoryEntry> history;
  if (Status s = ReadHistory(store, request, &history); !s.ok()) return s;

  const GridGeometry geometry(store.params().resolution, store.params().tile_size);
  // Forward: what may differ.
  // Nothing before the first revised scan differs; from it on, its old tiles may.
  uint64_t first_revised = UINT64_MAX;
  if (!request.replacements.empty()) first_revised = request.replacements.begin()->first;
  for (uint64_t v : request.revised_in_log) first_revised = std::min(first_revised, v);
  AffectedTiles region;
  bool seeded = false;
  auto seed = [&] {
    if (!seeded) region.Seed(request.seed_tiles);
    seeded = true;
  };
  for (const HistoryEntry& e : history) {
    if (e.version >= first_revised) seed();
    if (e.scan == nullptr) continue;  // a clear makes its tiles equal in both histories
    region.Add(*e.scan, e.revised);
  }
  seed();  // (every revised scan was removed)
  const std::set<TileKey>& affected = region.tiles();
  // Backward: what the rebuild of `affected` reads.
  std::set<TileKey> needed = affected;
  for (auto it = history.rbegin(); it != history.rend(); ++it) {
    if (it->scan == nullptr) {
      it->replay = AnyInRange(geometry.TileOf(it->clear_box.min),
                              geometry.TileOf(it->clear_box.max), needed);
      continue;
    }
    const std::vector<TileKey> outputs = it->scan->ChangeableTiles();
    if (!AnyIn(outputs, needed)) continue;
    it->replay = true;
    needed.insert(outputs.begin(), outputs.end());
    needed.insert(it->scan->read_tiles.begin(), it->scan->read_tiles.end());
  }

  Reintegration out;
  out.affected.assign(affected.begin(), affected.end());
  out.needed.assign(needed.begin(), needed.end());
  out.records_in_history = history.size();
  for (const HistoryEntry& e : history) out.records_replayed += e.replay ? 1 : 0;
  if (request.plan_only) return out;

  if (Status s = Replay(store, request.base, history, &out); !s.ok()) return s;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace bgkmap::storage
