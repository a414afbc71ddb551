// The engine's per-thread scratch buffers (bgkmap/core/thread_scratch.h): kept from scan to scan
// within their bound, handed back by ReleaseThreadScratch, and never part of what a map is.
#include "bgkmap/core/thread_scratch.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <memory>
#include <thread>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

MapParams Params() {
  MapParams p;
  p.resolution = 0.1;
  p.kernel_length = 0.3;
  p.dynamics = Dynamics::kOn;
  return p;
}

std::vector<Point3f> StreetScan(int s) {
  const Eigen::Vector3d origin(1.0 * s, 0.3 * s, 1.2);
  return testing::SampleSurface(testing::Surface(testing::RollingWithStep), origin, 8.0, 20000,
                                11 + s);
}

void Integrate(TerrainMap& map, int s) {
  const Eigen::Vector3d origin(1.0 * s, 0.3 * s, 1.2);
  ASSERT_TRUE(
      map.IntegrateScan(StreetScan(s), testing::At(origin), false, int64_t{1'000'000'000} * (s + 1))
          .ok());
}

// Every statistic of every tile, bit for bit.
void ExpectSameTiles(const TerrainMap& a, const TerrainMap& b) {
  int tiles = 0;
  a.ForEachTile([&](TileKey k, const Tile& ta) {
    ++tiles;
    const Tile* tb = b.FindTile(k);
    ASSERT_NE(tb, nullptr) << k.x << ", " << k.y;
    for (int i = 0; i < ta.tile_size() * ta.tile_size(); ++i) {
      const Tile::CellStats x = ta.CellAt(i), y = tb->CellAt(i);
      ASSERT_EQ(std::bit_cast<uint64_t>(x.w), std::bit_cast<uint64_t>(y.w)) << i;
      ASSERT_EQ(std::bit_cast<uint64_t>(x.s), std::bit_cast<uint64_t>(y.s)) << i;
      ASSERT_EQ(std::bit_cast<uint64_t>(x.q), std::bit_cast<uint64_t>(y.q)) << i;
      ASSERT_EQ(std::bit_cast<uint32_t>(x.a), std::bit_cast<uint32_t>(y.a)) << i;
      ASSERT_EQ(std::bit_cast<uint32_t>(x.b), std::bit_cast<uint32_t>(y.b)) << i;
    }
  });
  EXPECT_GT(tiles, 0);
  EXPECT_EQ(tiles, static_cast<int>(b.tile_count()));
}

TEST(ThreadScratchTest, ReleaseHandsBackTheBuffersAndChangesNoMap) {
  // On a fresh thread: this test's own buffers only.
  std::thread([] {
    std::unique_ptr<TerrainMap> kept = std::move(TerrainMap::Create(Params())).value();
    std::unique_ptr<TerrainMap> released = std::move(TerrainMap::Create(Params())).value();
    EXPECT_EQ(ThreadScratchBytes(), 0u);
    for (int s = 0; s < 4; ++s) Integrate(*kept, s);
    for (int s = 0; s < 4; ++s) {
      Integrate(*released, s);
      // A scan of 20k points keeps its binned points, sort keys and seen tops.
      EXPECT_GT(ThreadScratchBytes(), size_t{20000} * 16) << "scan " << s;
      ReleaseThreadScratch();
      EXPECT_EQ(ThreadScratchBytes(), 0u) << "scan " << s;
    }
    ExpectSameTiles(*kept, *released);
  }).join();
}

TEST(ThreadScratchTest, ReleaseOnAThreadThatNeverScannedIsHarmless) {
  std::thread([] {
    ReleaseThreadScratch();
    EXPECT_EQ(ThreadScratchBytes(), 0u);
  }).join();
}

TEST(ThreadScratchTest, ScansOverManyTilesKeepTheirSlabsWithinTheBound) {
  // One point in each of ~600 tiles within 90 m, seen twice: the second scan's rays enter
  // every tile the first made, so it computes a seen-top slab (32 KiB) for each, 19 MiB in all.
  std::thread([] {
    std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(Params())).value();
    const double tile_m = 6.4;
    std::vector<Point3f> points;
    for (int ty = -14; ty <= 14; ++ty) {
      for (int tx = -14; tx <= 14; ++tx) {
        const double x = (tx + 0.5) * tile_m, y = (ty + 0.5) * tile_m;
        if (std::hypot(x, y) > 90 || std::hypot(x, y) < 3) continue;
        for (int k = 0; k < 9; ++k) {  // a 3 x 3 patch of cells: values and features
          points.push_back({static_cast<float>(x + 0.1 * (k % 3)),
                            static_cast<float>(y + 0.1 * (k / 3)), -2.0f});
        }
      }
    }
    ASSERT_GT(points.size(), size_t{9} * 500);
    const Pose at = testing::At(Eigen::Vector3d(0, 0, 2.0));
    ASSERT_TRUE(map->IntegrateScan(points, at, false, 1'000'000'000).ok());
    ASSERT_GT(map->tile_count(), 500u);
    ASSERT_TRUE(map->IntegrateScan(points, at, false, 2'000'000'000).ok());
    // The slabs stay at 8 MiB at most; the other buffers hold a few points' worth.
    EXPECT_LE(ThreadScratchBytes(), (size_t{8} << 20) + (size_t{1} << 20));
    EXPECT_GT(ThreadScratchBytes(), size_t{4} << 20);  // the slabs were used and kept
  }).join();
}

}  // namespace
}  // namespace bgkmap
