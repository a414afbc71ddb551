#include "bgkmap/storage/recovery.h"

#include <algorithm>
#include <chrono>
#include <set>
#include <unordered_set>

#include "bgkmap/storage/reintegration.h"

namespace bgkmap::storage {
namespace {

// Loads the stored tiles a replayed record needs, each at most once per recovery.
class TileLoader {
 public:
  TileLoader(const TileStore& store, TerrainMap& map, RecoveryReport& report)
      : store_(store), map_(map), report_(report) {}

  void Ensure(TileKey key) {
    if (map_.FindTile(key) != nullptr || !tried_.insert(key).second) return;
    Result<bool> loaded = LoadTileInto(store_, key, map_);
    if (!loaded.ok()) {
      report_.corrupt_tiles.push_back(key);
    } else if (*loaded) {
      ++report_.tiles_loaded;
    }
  }

  // Loads the stored tiles in `box` and appends their keys to `keys`.
  Status EnsureBox(const CellBox& box, std::set<TileKey>* keys) {
    const TileKey lo = map_.geometry().TileOf(box.min), hi = map_.geometry().TileOf(box.max);
    Result<std::vector<StoredTileInfo>> stored = store_.ListTiles(lo, hi);
    if (!stored.ok()) return stored.status();
    for (const StoredTileInfo& info : *stored) {
      Ensure(info.key);
      keys->insert(info.key);
    }
    return Status::Ok();
  }

 private:
  const TileStore& store_;
  TerrainMap& map_;
  RecoveryReport& report_;
  std::unordered_set<TileKey, TileKeyHash> tried_;
};

}  // namespace

void InstallTiles(std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles,
                  uint64_t version, TerrainMap& map) {
  for (size_t i = 0; i < keys.size(); ++i) {
    // An empty tile rather than none: the stored copy, older, must not be loaded in its place.
    Tile tile = tiles[i] != nullptr
                    ? *tiles[i]
                    : Tile(map.params().tile_size, KeepsPlaneMoments(map.params().method));
    tile.set_version(version);
    map.SetTile(keys[i], tile);
  }
}

Result<bool> LoadTileInto(const TileStore& store, TileKey key, TerrainMap& map) {
  Result<std::unique_ptr<Tile>> tile = store.LoadTile(key);
  if (!tile.ok()) return tile.status();
  if (!*tile) return false;
  map.SetTile(key, **tile);
  return true;
}

Status LoadAllTiles(const TileStore& store, TerrainMap& map, std::vector<TileKey>* corrupt) {
  Result<std::vector<StoredTileInfo>> stored = store.ListTiles();
  if (!stored.ok()) return stored.status();
  for (const StoredTileInfo& info : *stored) {
    if (map.FindTile(info.key) != nullptr) continue;
    Result<bool> loaded = LoadTileInto(store, info.key, map);
    if (!loaded.ok()) {
      if (loaded.status().code() != Status::Code::kDataLoss) return loaded.status();
      if (corrupt) corrupt->push_back(info.key);
    }
  }
  return Status::Ok();
}

Result<RecoveryReport> RecoverMap(const TileStore& store, TerrainMap& map) {
  const auto start = std::chrono::steady_clock::now();
  RecoveryReport report;
  report.checkpoint_version = store.checkpoint_version();
  map.set_version(report.checkpoint_version);
  TileLoader loader(store, map, report);
  std::set<TileKey> touched;

  const Status walked = store.log().ForEach(
      report.checkpoint_version, [&](uint64_t version, Result<LogRecord> record) -> Status {
        if (!record.ok()) {
          report.corrupt_records.push_back(version);
          return Status::Ok();
        }
        if (record->type == LogRecord::Type::kScan) {
          const PreparedScan& scan = *record->scan;
          for (const TileKey& k : scan.write_tiles) loader.Ensure(k);
          for (const TileKey& k : scan.read_tiles) loader.Ensure(k);
          for (const TileKey& k : scan.clear_tiles) loader.Ensure(k);
          touched.insert(scan.write_tiles.begin(), scan.write_tiles.end());
          touched.insert(scan.clear_tiles.begin(), scan.clear_tiles.end());
          const TileWindow window = map.MakeWindow(scan);
          map.Integrate(scan, window, version);
          map.set_version(version);
          ++report.scans_replayed;
        } else if (record->type == LogRecord::Type::kCorrection) {
          // Rebuilt as the live server did (reintegration.h): the log already holds the
          // revised records.
          ReintegrationRequest request;
          request.base = record->base_version;
          request.end = version;
          request.seed_tiles = record->seed_tiles;
          request.revised_in_log = record->revised_versions;
          Result<Reintegration> rebuilt = Reintegrate(store, request);
          if (!rebuilt.ok()) {
            return Status::DataLoss("replaying correction " + std::to_string(version) + ": " +
                                    rebuilt.status().message());
          }
          InstallTiles(rebuilt->affected, rebuilt->tiles, version, map);
          touched.insert(rebuilt->affected.begin(), rebuilt->affected.end());
          map.set_version(version);
          ++report.corrections_replayed;
        } else {
          if (Status s = loader.EnsureBox(record->clear_box, &touched); !s.ok()) return s;
          map.ClearBox(record->clear_box, version);
          map.set_version(version);
          ++report.clears_replayed;
        }
        return Status::Ok();
      });
  if (!walked.ok()) return walked;
  map.set_version(std::max(map.version(), store.map_version()));
  report.map_version = map.version();
  report.touched_tiles.assign(touched.begin(), touched.end());
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace bgkmap::storage
