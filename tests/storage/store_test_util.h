// Shared by the storage tests and the crash writer: temporary directories, deterministic scans,
// "what the server does" (apply + log) and bitwise map comparison.
#pragma once

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_store.h"

namespace bgkmap::storage::testing {

class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "bgkmap-store-XXXXXX").string();
    path_ = mkdtemp(tmpl.data());
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string Sub(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// Small, fast maps: 0.2 m cells in 16-cell tiles, so a few scans span dozens of tiles.
inline MapParams SmallParams() {
  MapParams p;
  p.resolution = 0.2;
  p.kernel_length = 0.6;
  p.robot_radius = 0.6;
  p.tile_size = 16;
  return p;
}

inline double Terrain(double x, double y) {
  return 0.3 * std::sin(0.4 * x) + 0.2 * std::cos(0.3 * y) + (x > 6.0 ? 0.25 : 0.0);
}

// Scan `index` of robot `robot`: `points` points within 6 m of a pose along the robot's own
// lane. Overlapping lanes make scans depend on each other, as real ones do.
inline std::shared_ptr<const PreparedScan> MakeScan(const MapParams& params, int robot, int index,
                                                    int points = 1500) {
  std::mt19937 rng(1000u * robot + index);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  const Eigen::Vector3d origin(0.5 * index, 2.0 * robot, 1.5);
  std::vector<Point3f> pts;
  while (static_cast<int>(pts.size()) < points) {
    const double dx = u(rng), dy = u(rng);
    if (dx * dx + dy * dy > 36.0 || dx * dx + dy * dy < 1.5) continue;
    pts.push_back({static_cast<float>(dx), static_cast<float>(dy),
                   static_cast<float>(Terrain(origin.x() + dx, origin.y() + dy) - origin.z())});
  }
  Pose pose;
  pose.translation = origin;
  Result<PreparedScan> scan = PrepareScan(params, pts, pose);
  return std::make_shared<const PreparedScan>(std::move(scan).value());
}

// Scan `index` of `robot` as the sensor saw it (RawScan): points in the sensor frame and the
// true pose, the same points as MakeScan's.
inline RawScan MakeRawScan(int robot, int index) {
  std::mt19937 rng(1000u * robot + index);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  RawScan source;
  source.pose.translation = Eigen::Vector3d(0.5 * index, 2.0 * robot, 1.5);
  const Eigen::Vector3d& o = source.pose.translation;
  while (source.points.size() < 1500) {
    const double dx = u(rng), dy = u(rng);
    if (dx * dx + dy * dy > 36.0 || dx * dx + dy * dy < 1.5) continue;
    source.points.push_back({static_cast<float>(dx), static_cast<float>(dy),
                             static_cast<float>(Terrain(o.x() + dx, o.y() + dy) - o.z())});
  }
  return source;
}

// Integrates `scan` as map version `version`, as the server does; returns the changed tiles.
inline std::vector<TileKey> Apply(TerrainMap& map, const PreparedScan& scan, uint64_t version) {
  const TileWindow window = map.MakeWindow(scan);
  ScanReport report = map.Integrate(scan, window, version);
  map.set_version(version);
  return report.changed_tiles;
}

// Tracks the tiles changed since the last checkpoint and writes them in one.
class Checkpointer {
 public:
  void MarkDirty(const std::vector<TileKey>& keys) { dirty_.insert(keys.begin(), keys.end()); }
  Status Checkpoint(TileStore& store, const TerrainMap& map) {
    std::vector<TileUpdate> updates;
    for (const TileKey& k : dirty_) updates.push_back({k, map.FindTile(k)});
    Status s = store.Checkpoint(map.version(), updates);
    if (s.ok()) dirty_.clear();
    return s;
  }

 private:
  std::set<TileKey> dirty_;
};

// Tiles of `a` and `b` whose statistics differ (bitwise; a missing tile equals an all-zero one),
// or, with `versions`, whose tile versions differ where both have the tile.
inline ::testing::AssertionResult CompareTiles(const TerrainMap& a, const TerrainMap& b,
                                               bool versions) {
  std::set<TileKey> keys;
  a.ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
  b.ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
  const Tile zero(a.params().tile_size, KeepsPlaneMoments(a.params().method));
  int differing = 0;
  std::string first;
  for (const TileKey& k : keys) {
    const Tile* ta = a.FindTile(k);
    const Tile* tb = b.FindTile(k);
    const bool same_version = !versions || !ta || !tb || ta->version() == tb->version();
    if ((!((ta ? *ta : zero) == (tb ? *tb : zero)) || !same_version) && differing++ == 0) {
      first = std::to_string(k.x) + ", " + std::to_string(k.y);
    }
  }
  if (differing > 0) {
    return ::testing::AssertionFailure()
           << differing << " of " << keys.size() << " tiles differ, first " << first;
  }
  return ::testing::AssertionSuccess() << keys.size() << " tiles identical";
}

// Bitwise equality of statistics and tile versions; a missing tile equals an all-zero one.
inline ::testing::AssertionResult MapsIdentical(const TerrainMap& a, const TerrainMap& b) {
  if (a.version() != b.version()) {
    return ::testing::AssertionFailure()
           << "map versions differ: " << a.version() << " vs " << b.version();
  }
  return CompareTiles(a, b, /*versions=*/true);
}

// Bitwise equality of the statistics (W, S, A, B) alone: tile and map versions are ignored, so
// two maps built from the same changes at other version numbers compare equal. A missing tile
// equals an all-zero one.
inline ::testing::AssertionResult StatisticsIdentical(const TerrainMap& a, const TerrainMap& b) {
  return CompareTiles(a, b, /*versions=*/false);
}

inline std::unique_ptr<TerrainMap> NewMap(const MapParams& params) {
  return std::move(TerrainMap::Create(params)).value();
}

// The crash and power-cut trials' check: `store` recovers cleanly to exactly the map of the kept
// versions replayed in order (version v is MakeScan(params, v % robots, v / robots)), and each
// robot's last logged sequence is that of its last kept scan.
inline void ExpectRecoveryEqualsReplay(const TileStore& store, const MapParams& params,
                                       const std::set<uint64_t>& kept, int robots) {
  auto recovered = NewMap(params);
  auto report = RecoverMap(store, *recovered);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->clean());
  ASSERT_TRUE(LoadAllTiles(store, *recovered).ok());
  auto reference = NewMap(params);
  std::map<std::string, uint64_t> last_sequence;
  for (uint64_t v : kept) {
    const int robot = static_cast<int>(v % robots), index = static_cast<int>(v / robots);
    Apply(*reference, *MakeScan(params, robot, index), v);
    last_sequence["robot-" + std::to_string(robot)] = index + 1;
  }
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
  for (const auto& [robot, sequence] : last_sequence) {
    EXPECT_EQ(store.LastSequence(robot), sequence) << robot;
  }
}

}  // namespace bgkmap::storage::testing
