// A served map that integrates each scan in bands on its workers (ServedMapOptions::scan_bands,
// core/scan_bands.h) holds the same map, bit for bit with the same tile versions, and reports the
// same changed tiles, as one that integrates every scan whole: with a sensor's free-space rays
// clearing a box that drove off, and a clear between the scans.
#include <gtest/gtest.h>

#include <future>

#include "serving_test_util.h"

namespace bgkmap {
namespace {

using testing::FakeDurability;
using testing::SameStatistics;

MapParams Params() {
  MapParams p;
  p.tile_size = 16;  // several tiles across a scan, so that the bands cut between them
  p.sensor_height = 1.5;
  return p;
}

// Ground at z = 0 within 6 m of a sensor 1.5 m above (cx, cy), with a 1 m box 2 m east of it
// while `box`, in the sensor's frame.
std::shared_ptr<const PreparedScan> SensorScan(const MapParams& params, float cx, float cy,
                                               bool box) {
  std::vector<Point3f> points;
  for (float x = -6; x <= 6; x += 0.05f) {
    for (float y = -6; y <= 6; y += 0.05f) {
      if (x * x + y * y > 36) continue;
      const bool on_box = box && x > 1.5f && x < 2.5f && y > -0.5f && y < 0.5f;
      points.push_back({x, y, (on_box ? 1.0f : 0.0f) - 1.5f});
    }
  }
  Pose pose;
  pose.translation = {cx, cy, 1.5};
  Result<PreparedScan> p = PrepareScan(params, points, pose);
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  return std::make_shared<PreparedScan>(std::move(p).value());
}

struct Served {
  explicit Served(int bands)
      : durability(Params()), map(TerrainMap::Create(Params()).value(), durability, pool, [&] {
          ServedMapOptions o;
          o.max_robots = 4;
          o.scan_bands = bands;
          o.scan_band_cells = 500;  // these scans have ~11k observed cells
          return o;
        }()) {}

  std::vector<TileKey> Scan(uint64_t sequence, float cx, float cy, bool box) {
    std::promise<ScanOutcome> done;
    EXPECT_EQ(map.SubmitScan({"r", sequence, {}, {}}, SensorScan(map.params(), cx, cy, box),
                             [&done](ScanOutcome o) { done.set_value(std::move(o)); }),
              ServedMap::Admission::kAdmitted);
    ScanOutcome outcome = done.get_future().get();
    EXPECT_TRUE(outcome.status.ok()) << outcome.status.ToString();
    return outcome.changed_tiles;
  }
  void Clear(const CellBox& box) {
    std::promise<ClearOutcome> done;
    map.SubmitClear(box, [&done](const ClearOutcome& o) { done.set_value(o); });
    ASSERT_TRUE(done.get_future().get().status.ok());
  }

  boost::asio::thread_pool pool{3};
  FakeDurability durability;
  ServedMap map;
};

TEST(ScanBandsServedTest, BandedScansLeaveTheMapWholeScansLeave) {
  Served whole(1), banded(3);
  uint64_t sequence = 0;
  for (int s = 0; s < 6; ++s) {
    ++sequence;
    const float cx = 0.8f * s, cy = 0.3f * s;
    EXPECT_EQ(banded.Scan(sequence, cx, cy, s < 3), whole.Scan(sequence, cx, cy, s < 3))
        << "scan " << s;
    if (s == 3) {
      const CellBox box{{-20, -20}, {5, 5}};
      banded.Clear(box);
      whole.Clear(box);
    }
  }
  EXPECT_EQ(whole.map.banded_scans(), 0u);
  EXPECT_EQ(banded.map.banded_scans(), 6u) << "a scan was integrated whole";
  const std::unique_ptr<TerrainMap> a = banded.map.Snapshot(), b = whole.map.Snapshot();
  EXPECT_TRUE(SameStatistics(*a, *b));
  a->ForEachTile([&](TileKey key, const Tile& tile) {
    const Tile* other = b->FindTile(key);
    ASSERT_NE(other, nullptr);
    EXPECT_EQ(tile.version(), other->version()) << key.x << "," << key.y;
  });
  EXPECT_GT(a->CountKnownCells(), 10000);
}

}  // namespace
}  // namespace bgkmap
