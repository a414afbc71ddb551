// Results must not depend on the tile size or on where tile borders fall: the integrator adds
// each cell's contributions in one canonical order, so the statistics are bitwise identical.
#include <gtest/gtest.h>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

struct Scan {
  std::vector<Point3f> points;
  Pose pose;
};

// Resolution and offsets are powers of two so a shifted map bins every point exactly 3 cells
// over (no rounding in q.x + shift or in q.x / res).
constexpr double kRes = 0.125;

std::vector<Scan> MakeScans() {
  std::vector<Scan> scans;
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector3d origin(1.5 * s, 0.25 * s, 1.0);
    scans.push_back({testing::SampleSurface(testing::RollingWithStep, origin, 5.0, 6000, 100 + s),
                     testing::At(origin)});
  }
  return scans;
}

std::unique_ptr<TerrainMap> Build(int tile_size, Method method, double shift_x = 0) {
  MapParams p;
  p.resolution = kRes;
  p.kernel_length = 0.5;
  p.robot_radius = 0.375;
  p.tile_size = tile_size;
  p.method = method;
  auto map = std::move(TerrainMap::Create(p)).value();
  for (Scan s : MakeScans()) {
    s.pose.translation.x() += shift_x;
    EXPECT_TRUE(map->IntegrateScan(s.points, s.pose).ok());
  }
  return map;
}

// Compares every cell of `a` with the cell `shift` cells east in `b`, bit for bit.
void ExpectSameStatistics(const TerrainMap& a, const TerrainMap& b, int shift = 0) {
  const CellBox box = a.KnownBounds();
  ASSERT_FALSE(box.empty());
  CellBox shifted = box;
  shifted.min.x += shift;
  shifted.max.x += shift;
  EXPECT_EQ(b.KnownBounds(), shifted);
  EXPECT_EQ(a.CountKnownCells(), b.CountKnownCells());
  int64_t compared = 0;
  for (int y = box.min.y; y <= box.max.y; ++y) {
    for (int x = box.min.x; x <= box.max.x; ++x) {
      const Tile* ta = a.FindTile(a.geometry().TileOf({x, y}));
      const Tile* tb = b.FindTile(b.geometry().TileOf({x + shift, y}));
      const int ia = a.geometry().LocalIndex({x, y});
      const int ib = b.geometry().LocalIndex({x + shift, y});
      const bool known_a = ta != nullptr && ta->IsKnown(ia);
      const bool known_b = tb != nullptr && tb->IsKnown(ib);
      ASSERT_EQ(known_a, known_b) << x << "," << y;
      if (!known_a) continue;
      ASSERT_EQ(ta->w()[ia], tb->w()[ib]) << x << "," << y;
      ASSERT_EQ(ta->s()[ia], tb->s()[ib]) << x << "," << y;
      ASSERT_EQ(ta->a()[ia], tb->a()[ib]) << x << "," << y;
      ASSERT_EQ(ta->b()[ia], tb->b()[ib]) << x << "," << y;
      ++compared;
    }
  }
  EXPECT_GT(compared, 1000);
}

class TilingInvarianceTest : public ::testing::TestWithParam<Method> {};

TEST_P(TilingInvarianceTest, TileSizes8And64And256GiveIdenticalMaps) {
  auto m64 = Build(64, GetParam());
  ExpectSameStatistics(*m64, *Build(8, GetParam()));
  ExpectSameStatistics(*m64, *Build(256, GetParam()));
}

// Tile sizes that are not powers of two: 20 ends each tile with a partial 4-cell block of the
// free-space test's 8 x 8 blocks (core/src/tile_slabs.h), whose highest tops decide which rays are
// walked (mutation: a block stepping that ignores tile borders skips contradicting rays).
TEST_P(TilingInvarianceTest, TileSizes20And48GiveTheMapOf64) {
  auto m64 = Build(64, GetParam());
  ExpectSameStatistics(*m64, *Build(20, GetParam()));
  ExpectSameStatistics(*m64, *Build(48, GetParam()));
}

TEST_P(TilingInvarianceTest, ShiftingAcrossTileBordersGivesTheShiftedMap) {
  auto base = Build(8, GetParam());
  ExpectSameStatistics(*base, *Build(8, GetParam(), 3 * kRes), 3);
  ExpectSameStatistics(*base, *Build(8, GetParam(), -13 * kRes), -13);
}

INSTANTIATE_TEST_SUITE_P(AllMethods, TilingInvarianceTest,
                         ::testing::Values(Method::kBgkPlus, Method::kBgkTrav, Method::kBaseline,
                                           Method::kOneStep, Method::kBgkObstacle,
                                           Method::kBgkLocalLinear),
                         [](const ::testing::TestParamInfo<Method>& param_info) {
                           std::string n(MethodName(param_info.param));
                           for (char& c : n) c = std::isalnum(c) ? c : '_';
                           return n;
                         });

}  // namespace
}  // namespace bgkmap
