// Scans and a served map over FakeDurability, for the serving-layer tests.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <future>
#include <memory>
#include <vector>

#include "bgkmap/core/scan.h"
#include "fake_durability.h"
#include "serving/served_map.h"

namespace bgkmap::testing {

// A ring of flat ground at height `z` around (cx, cy), as the sensor at the origin sees it.
inline std::shared_ptr<const PreparedScan> GroundScan(const MapParams& params, float cx, float cy,
                                                      float z = -1.0f) {
  std::vector<Point3f> points;
  for (float x = -4; x <= 4; x += 0.05f) {
    for (float y = -4; y <= 4; y += 0.05f) {
      if (x * x + y * y > 2) points.push_back({cx + x, cy + y, z});
    }
  }
  Result<PreparedScan> p = PrepareScan(params, points, Pose{}, /*frame_is_map=*/true);
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  return std::make_shared<PreparedScan>(std::move(p).value());
}

// A served map (in-memory tables, FakeDurability as its store) and helpers that wait.
class ServedMapFixture : public ::testing::Test {
 protected:
  explicit ServedMapFixture(MapParams params = {}, uint64_t memory_limit = 0)
      : durability_(params),
        map_(TerrainMap::Create(params).value(), durability_, pool_, Options(memory_limit)) {}

  static ServedMapOptions Options(uint64_t memory_limit) {
    ServedMapOptions o;
    o.max_robots = 16;
    o.tile_memory_limit_bytes = memory_limit;
    return o;
  }

  ScanOutcome Scan(uint64_t sequence, float cx = 0, float cy = 0, float z = -1.0f) {
    std::promise<ScanOutcome> done;
    const ServedMap::Admission a =
        map_.SubmitScan({"r", sequence, {}, {}}, GroundScan(map_.params(), cx, cy, z),
                        [&done](ScanOutcome o) { done.set_value(std::move(o)); });
    EXPECT_EQ(a, ServedMap::Admission::kAdmitted);
    if (a != ServedMap::Admission::kAdmitted) {  // `done` is never called
      return {0, {}, Status::FailedPrecondition("not admitted")};
    }
    return done.get_future().get();
  }

  ClearOutcome Clear(const CellBox& box) {
    std::promise<ClearOutcome> done;
    map_.SubmitClear(box, [&done](const ClearOutcome& o) { done.set_value(o); });
    return done.get_future().get();
  }

  ImportOutcome Import(const std::vector<TileKey>& keys,
                       const std::vector<std::unique_ptr<Tile>>& tiles) {
    std::promise<ImportOutcome> done;
    map_.SubmitImport(keys, tiles, [&done](const ImportOutcome& o) { done.set_value(o); });
    return done.get_future().get();
  }

  boost::asio::thread_pool pool_{2};
  FakeDurability durability_;
  ServedMap map_;
};

// Whether two maps hold bitwise the same statistics (versions aside).
inline bool SameStatistics(const TerrainMap& a, const TerrainMap& b) {
  if (a.tile_count() != b.tile_count()) return false;
  bool same = true;
  a.ForEachTile([&](TileKey k, const Tile& t) {
    const Tile* o = b.FindTile(k);
    same = same && o != nullptr && t == *o;
  });
  return same;
}

}  // namespace bgkmap::testing
