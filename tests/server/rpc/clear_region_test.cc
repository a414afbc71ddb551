// ClearRegion: the box becomes unknown, the rest is untouched, and a clear ordered among
// concurrent scans gives the map of the sequential order of versions.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <thread>
#include <variant>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

CellBox CellsOf(const MetricBox& b, double res) {
  return {{static_cast<int>(std::floor(b.min_x / res + 1e-6)),
           static_cast<int>(std::floor(b.min_y / res + 1e-6))},
          {static_cast<int>(std::ceil(b.max_x / res - 1e-6)) - 1,
           static_cast<int>(std::ceil(b.max_y / res - 1e-6)) - 1}};
}

TEST(ClearRegionTest, ForgetsTheBoxOnly) {
  ServerFixture fixture;
  std::vector<ScanData> data;
  for (const OwnedScan& s : StreetScans()) data.push_back(s.Data());
  ASSERT_TRUE(fixture.client().IngestAll(data).ok());
  const MetricBox cleared{-10, -5, 12.5, 7};
  RpcResult<ClearResult> clear = fixture.client().ClearRegion(cleared);
  ASSERT_TRUE(clear.ok()) << clear.status().ToString();
  EXPECT_EQ(clear->map_version, 4u);
  EXPECT_FALSE(clear->changed_tiles.empty());

  std::vector<const OwnedScan*> all;
  for (const OwnedScan& s : StreetScans()) all.push_back(&s);
  std::unique_ptr<TerrainMap> offline = OfflineMap(all);
  offline->ClearBox(CellsOf(cleared, 0.1));
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));

  const MetricBox around{-20, -20, 20, 20};
  RpcResult<Raster> region = fixture.client().QueryRegion({around, {Layer::kElevation}, 1});
  ASSERT_TRUE(region.ok());
  size_t known_inside = 0;
  for (int64_t row = 0; row < region->rows; ++row) {
    for (int64_t col = 0; col < region->cols; ++col) {
      const double x = region->x0 + (col + 0.5) * 0.1, y = region->y1 - (row + 0.5) * 0.1;
      const bool inside =
          x > cleared.min_x && x < cleared.max_x && y > cleared.min_y && y < cleared.max_y;
      known_inside += inside && !std::isnan(region->data[0][row * region->cols + col]);
    }
  }
  EXPECT_EQ(known_inside, 0u);
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->known_cells, static_cast<uint64_t>(offline->CountKnownCells()));
  EXPECT_EQ(info->map_version, 4u);
}

TEST(ClearRegionTest, ClearsAmongConcurrentScansApplyInVersionOrder) {
  ServerFixture fixture;
  const std::vector<OwnedScan> scans = SubScans("c", 6);
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  std::vector<ScanAck> acks;
  std::thread robot([&] {
    RpcResult<std::vector<ScanAck>> r = fixture.client().IngestAll(data);
    ASSERT_TRUE(r.ok());
    acks = *r;
  });
  std::unique_ptr<Client> admin = fixture.NewClient();
  std::vector<std::pair<uint64_t, MetricBox>> clears;
  // Each clear after the previous one waits until the robot's scans have moved the map on (Info's
  // map version), instead of a fixed sleep, so the clears interleave with the scans however fast
  // the machine is; a generous deadline in case the robot has already finished.
  for (int i = 0; i < 4; ++i) {
    if (i > 0) {
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
      for (;;) {
        RpcResult<MapInfo> info = admin->Info();
        ASSERT_TRUE(info.ok());
        if (info->map_version > clears.back().first ||
            info->scans_applied >= static_cast<uint64_t>(scans.size()) ||
            std::chrono::steady_clock::now() > deadline) {
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
    const MetricBox box{-30.0 + 12 * i, -8, -18.0 + 12 * i, 8};
    RpcResult<ClearResult> c = admin->ClearRegion(box);
    ASSERT_TRUE(c.ok());
    clears.emplace_back(c->map_version, box);
  }
  robot.join();
  ASSERT_EQ(acks.size(), scans.size());

  // Replay scans and clears in version order.
  std::map<uint64_t, std::variant<const OwnedScan*, MetricBox>> ops;
  for (size_t i = 0; i < acks.size(); ++i) ops[acks[i].map_version] = &scans[i];
  for (const auto& [v, box] : clears) ops[v] = box;
  ASSERT_EQ(ops.size(), scans.size() + clears.size());
  const bool interleaved = std::any_of(clears.begin(), clears.end(), [&](const auto& c) {
    return c.first > acks.front().map_version && c.first < acks.back().map_version;
  });
  EXPECT_TRUE(interleaved) << "no clear landed between scans";
  EXPECT_EQ(ops.rbegin()->first, ops.size());
  std::unique_ptr<TerrainMap> offline = std::move(TerrainMap::Create(MapParams{})).value();
  for (const auto& [v, op] : ops) {
    if (const auto* s = std::get_if<const OwnedScan*>(&op)) {
      ASSERT_TRUE(
          offline->IntegrateScan(PointsAsIntegrated(**s, MapParams{}), WirePose((*s)->pose)).ok());
    } else {
      offline->ClearBox(CellsOf(std::get<MetricBox>(op), 0.1));
    }
  }
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));
}

}  // namespace
}  // namespace bgkmap::testing
