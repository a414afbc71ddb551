// storage.max_memory_mb: a map several times larger than the bound is built and queried with
// tiles evicted to the store and loaded back on demand, and every answer is exactly the answer
// of a map held wholly in memory: scans over evicted ground, region and point queries, clears of
// evicted tiles, and a restart that opens the store lazily.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "bgkmap/server/server_config.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

constexpr double kSiteSpacing = 300.0;  // metres between the places the robot maps
constexpr uint64_t kBoundMb = 2;

// The street sub-scans taken at `sites` places kSiteSpacing apart, then the first place again
// (ground that has been evicted by then), numbered 1.. in that order.
std::vector<OwnedScan> Tour(int sites) {
  const std::vector<OwnedScan> base = SubScans("tour", 4);
  std::vector<OwnedScan> scans;
  for (int site = 0; site <= sites; ++site) {
    for (const OwnedScan& s : base) {
      scans.push_back(s);
      scans.back().pose.tx += (site % sites) * kSiteSpacing;
      scans.back().sequence = scans.size();
    }
  }
  return scans;
}

ServerConfig BoundedConfig(const std::string& dir) {
  ServerConfig c = TestConfig();
  c.storage.data_dir = dir;
  c.storage.max_memory_mb = kBoundMb;
  c.storage.checkpoint_interval_s = 3600;  // only the bound makes checkpoints here
  return c;
}

std::unique_ptr<TerrainMap> OfflineOf(const std::vector<OwnedScan>& scans) {
  std::vector<const OwnedScan*> all;
  for (const OwnedScan& s : scans) all.push_back(&s);
  return OfflineMap(all);
}

CellBox CellsOf(const MetricBox& b, double res) {
  return {{static_cast<int>(std::floor(b.min_x / res + 1e-6)),
           static_cast<int>(std::floor(b.min_y / res + 1e-6))},
          {static_cast<int>(std::ceil(b.max_x / res - 1e-6)) - 1,
           static_cast<int>(std::ceil(b.max_y / res - 1e-6)) - 1}};
}

// Polls Info until the tiles in memory are within the bound (eviction runs in the background).
RpcResult<MapInfo> SettledInfo(Client& client) {
  RpcResult<MapInfo> info = client.Info();
  for (int i = 0; i < 100 && info.ok() && info->storage.has_value() &&
                  info->storage->resident_bytes > info->storage->memory_limit_bytes;
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    info = client.Info();
  }
  return info;
}

// Region queries around each site, and the known-cell summary, against the offline map.
void ExpectAnswersEqual(Client& client, const TerrainMap& offline, int sites) {
  for (int site = 0; site < sites; ++site) {
    const double x = site * kSiteSpacing;
    const MetricBox box{x - 25, -25, x + 25, 25};
    RpcResult<Raster> served = client.QueryRegion({box, {}, 1});
    ASSERT_TRUE(served.ok()) << served.status().ToString();
    EXPECT_TRUE(RastersMatch(*served, OfflineRegion(offline, box), 0.0)) << "site " << site;
  }
  RpcResult<MapInfo> info = client.Info();
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->known_cells, static_cast<uint64_t>(offline.CountKnownCells()));
  EXPECT_EQ(info->tile_count, offline.tile_count());
  EXPECT_EQ(info->known_cells_box, offline.KnownBounds());
}

TEST(BoundedMemoryTest, MapLargerThanTheBoundIsBuiltAndQueriedExactly) {
  TempDir dir("bgkmap_bounded");
  const int sites = 4;
  const std::vector<OwnedScan> scans = Tour(sites);
  const std::unique_ptr<TerrainMap> offline = OfflineOf(scans);
  const uint64_t bound = kBoundMb << 20;
  // The test means something only if the map is well beyond the bound.
  ASSERT_GT(offline->TileMemoryBytes(), 4 * bound);

  ServerFixture fixture(BoundedConfig(dir.str()));
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  ASSERT_TRUE(fixture.client().IngestAll(data).ok());

  RpcResult<MapInfo> info = SettledInfo(fixture.client());
  ASSERT_TRUE(info.ok() && info->storage.has_value());
  const StorageInfo& st = *info->storage;
  EXPECT_EQ(st.memory_limit_bytes, bound);
  EXPECT_LE(st.resident_bytes, bound);
  EXPECT_GT(st.tiles_evicted, 0u);
  EXPECT_GT(st.tiles_loaded, 0u);  // the last site revisits evicted ground
  // Scans over evicted ground integrated onto the stored statistics, bit for bit.
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));
  ExpectAnswersEqual(fixture.client(), *offline, sites);

  // Point queries spread over every site load what they need.
  std::vector<std::array<double, 2>> points;
  for (int site = 0; site < sites; ++site) {
    for (int i = 0; i < 50; ++i) points.push_back({site * kSiteSpacing - 20 + i * 0.8, 3.0});
  }
  RpcResult<PointValues> values = fixture.client().QueryPoints(points, {Layer::kElevation});
  ASSERT_TRUE(values.ok()) << values.status().ToString();
  for (size_t i = 0; i < points.size(); ++i) {
    const float expected = offline->EstimateAt(points[i][0], points[i][1]).Get(Layer::kElevation);
    const float got = values->values[i];
    EXPECT_TRUE((std::isnan(expected) && std::isnan(got)) || expected == got) << "point " << i;
  }
}

TEST(BoundedMemoryTest, ClearOfEvictedGroundAndRestartStayExact) {
  TempDir dir("bgkmap_bounded");
  const int sites = 3;
  std::vector<OwnedScan> scans = Tour(sites);
  scans.resize(scans.size() - SubScans("tour", 4).size());  // no revisit: site 0 stays evicted
  std::unique_ptr<TerrainMap> offline = OfflineOf(scans);
  const MetricBox cleared{-12, -6, 9, 8};  // site 0, mapped first, evicted since
  offline->ClearBox(CellsOf(cleared, offline->params().resolution));
  {
    ServerFixture fixture(BoundedConfig(dir.str()));
    std::vector<ScanData> data;
    for (const OwnedScan& s : scans) data.push_back(s.Data());
    ASSERT_TRUE(fixture.client().IngestAll(data).ok());
    RpcResult<MapInfo> before = SettledInfo(fixture.client());
    ASSERT_TRUE(before.ok());
    ASSERT_GT(before->storage->tiles_evicted, 0u);
    RpcResult<ClearResult> clear = fixture.client().ClearRegion(cleared);
    ASSERT_TRUE(clear.ok()) << clear.status().ToString();
    EXPECT_FALSE(clear->changed_tiles.empty());
    EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));
    ExpectAnswersEqual(fixture.client(), *offline, sites);
  }
  // Reopened lazily: nothing is loaded until asked for, and the answers are the same.
  ServerFixture fixture(BoundedConfig(dir.str()));
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok() && info->storage.has_value());
  EXPECT_EQ(info->storage->resident_tiles, 0u);
  ExpectAnswersEqual(fixture.client(), *offline, sites);
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));
}

// Export reads the store, so a map mostly evicted exports whole; importing it into a bounded
// server adds onto evicted tiles, which are loaded first.
TEST(BoundedMemoryTest, ExportAndImportOfAMapLargerThanTheBound) {
  TempDir dir("bgkmap_bounded");
  const int sites = 3;
  const std::vector<OwnedScan> scans = Tour(sites);
  const std::unique_ptr<TerrainMap> offline = OfflineOf(scans);
  const std::string archive = dir.str() + ".bgkmap";
  {
    ServerFixture fixture(BoundedConfig(dir.str()));
    std::vector<ScanData> data;
    for (const OwnedScan& s : scans) data.push_back(s.Data());
    ASSERT_TRUE(fixture.client().IngestAll(data).ok());
    RpcResult<ExportResult> exported = fixture.client().ExportMap(std::nullopt, archive);
    ASSERT_TRUE(exported.ok()) << exported.status().ToString();
    EXPECT_EQ(exported->tiles, offline->tile_count());
    // Imported onto itself: every statistic doubles, evicted tiles included.
    RpcResult<ImportResult> imported = fixture.client().ImportMap(archive);
    ASSERT_TRUE(imported.ok()) << imported.status().ToString();
    std::unique_ptr<TerrainMap> doubled = std::move(TerrainMap::Create(MapParams{})).value();
    offline->ForEachTile([&](TileKey k, const Tile& t) {
      doubled->AddTile(k, t);
      doubled->AddTile(k, t);
    });
    EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *doubled));
    RpcResult<MapInfo> info = SettledInfo(fixture.client());
    ASSERT_TRUE(info.ok());
    EXPECT_LE(info->storage->resident_bytes, info->storage->memory_limit_bytes);
  }
  ServerFixture fresh;  // in memory
  ASSERT_TRUE(fresh.client().ImportMap(archive).ok());
  EXPECT_TRUE(MapsEqual(*fresh.server().SnapshotMap(), *offline));
  fs::remove(archive);
}

// Queries race with ingestion, eviction and reloading of the ground they read: every answer is
// the map after some whole number of scans, never a tile missing or half evicted.
TEST(BoundedMemoryTest, ReadersRacingEvictionSeeWholeScans) {
  TempDir dir("bgkmap_bounded");
  const std::vector<OwnedScan> scans = Tour(3);  // site 0, 1, 2, then site 0 again
  const MetricBox box{-20, -20, 20, 20};         // site 0
  ServerFixture fixture(BoundedConfig(dir.str()));
  std::unique_ptr<Client> reader = fixture.NewClient();
  std::atomic<bool> done{false};
  std::vector<std::pair<uint64_t, Raster>> seen;
  std::thread querier([&] {
    while (!done.load()) {
      uint64_t version = 0;
      RpcResult<Raster> r = reader->QueryRegion({box, {}, 1}, &version);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      seen.emplace_back(version, std::move(r).value());
    }
  });
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  ASSERT_TRUE(fixture.client().IngestAll(data).ok());
  // A few more reads once the robot has left site 0 for good and the bound evicted it.
  RpcResult<MapInfo> info = SettledInfo(fixture.client());
  done = true;
  querier.join();
  ASSERT_TRUE(info.ok());
  EXPECT_GT(info->storage->tiles_evicted, 0u);
  ASSERT_GT(seen.size(), 3u);

  std::vector<Raster> states;  // site 0 after the first k scans
  std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(MapParams{})).value();
  states.push_back(OfflineRegion(*map, box));
  for (const OwnedScan& s : scans) {
    ASSERT_TRUE(map->IntegrateScan(PointsAsIntegrated(s, MapParams{}), WirePose(s.pose)).ok());
    states.push_back(OfflineRegion(*map, box));
  }
  for (const auto& [version, raster] : seen) {
    bool whole = false;
    for (size_t k = version; k < states.size() && !whole; ++k) {
      whole = RastersMatch(raster, states[k], 0.0);
    }
    EXPECT_TRUE(whole) << "a read at version " << version << " is no whole number of scans";
  }
}

TEST(BoundedMemoryTest, BoundNeedsADataDirectory) {
  ServerConfig c = TestConfig();
  c.storage.max_memory_mb = 64;
  const Status s = ValidateServerConfig(c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("storage.max_memory_mb"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace bgkmap::testing
