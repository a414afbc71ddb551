// The blocks a scan reports changed (ScanReport::changed_blocks, tile_blocks.h: what a region
// delta sends) cover every cell whose statistics the scan changed, bit for bit, for every
// method and with each of dynamics' rules (free-space evidence from a box that appears and
// goes, the footprint, forgetting); and they are a small part of a tile, not the whole of it.
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <map>
#include <memory>
#include <string>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/core/tile_blocks.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

// Every statistic of a cell, as bits.
std::vector<uint64_t> CellBits(const Tile& tile, int i) {
  const Tile::CellStats c = tile.CellAt(i);
  std::vector<uint64_t> out = {std::bit_cast<uint64_t>(c.w), std::bit_cast<uint64_t>(c.s),
                               std::bit_cast<uint64_t>(c.q), std::bit_cast<uint32_t>(c.a),
                               std::bit_cast<uint32_t>(c.b)};
  if (tile.has_plane()) {
    double m[Tile::kPlaneMoments];
    tile.PlaneOf(i, m);
    for (double v : m) out.push_back(std::bit_cast<uint64_t>(v));
  }
  return out;
}

constexpr int kAll = kTileBlocksPerSide * kTileBlocksPerSide;  // blocks in a tile

using Snapshot = std::map<TileKey, std::unique_ptr<Tile>>;

Snapshot Copy(const TerrainMap& map) {
  Snapshot out;
  map.ForEachTile([&](TileKey k, const Tile& t) { out[k] = std::make_unique<Tile>(t); });
  return out;
}

// Checks that every cell that differs between `before` and `map` lies in a reported block;
// returns the number of blocks reported.
int ExpectChangesInsideBlocks(const Snapshot& before, const TerrainMap& map,
                              const ScanReport& report, const std::string& what) {
  EXPECT_EQ(report.changed_blocks.size(), report.changed_tiles.size()) << what;
  std::map<TileKey, TileBlocks> reported;
  int blocks = 0;
  for (size_t i = 0; i < report.changed_tiles.size(); ++i) {
    reported[report.changed_tiles[i]] = report.changed_blocks[i];
    blocks += report.changed_blocks[i].Count();
  }
  const Snapshot after = Copy(map);
  std::map<TileKey, bool> keys;
  for (const auto& [k, t] : before) keys[k] = true;
  for (const auto& [k, t] : after) keys[k] = true;
  const int T = map.params().tile_size, shift = TileBlockShift(T);
  const Tile empty(T, KeepsPlaneMoments(map.params().method));
  for (const auto& [key, unused] : keys) {
    const Tile& a = before.count(key) ? *before.at(key) : empty;
    const Tile& b = after.count(key) ? *after.at(key) : empty;
    for (int i = 0; i < T * T; ++i) {
      if (CellBits(a, i) == CellBits(b, i)) continue;
      const TileBlocks bit = TileBlocksOf(shift, i % T, i / T, i % T, i / T);
      auto it = reported.find(key);
      if (it == reported.end() || !it->second.Contains(bit)) {
        ADD_FAILURE() << what << ": cell " << i << " of tile (" << key.x << ", " << key.y
                      << ") changed outside the reported blocks";
        return -1;
      }
    }
  }
  return blocks;
}

struct Case {
  std::string name;
  Method method;
  Dynamics dynamics;
  double sensor_height = 0;  // the footprint (dynamics on)
  double half_life_s = 0;    // forgetting (dynamics on)
  int tile_size = 64;
};

// A street: rolling ground, a 1 m box present in scans 2-3 only (it appears: returns above the
// map; it goes: rays below it), the sensor moving 1 m per scan.
double Ground(double x, double y) { return testing::RollingWithStep(x, y); }
double WithBox(double x, double y) {
  return Ground(x, y) + (std::abs(x - 4.0) < 0.6 && std::abs(y - 1.0) < 0.6 ? 1.0 : 0.0);
}

class ChangedBlocksTest : public ::testing::TestWithParam<Case> {};

TEST_P(ChangedBlocksTest, EveryChangedCellIsInAReportedBlock) {
  const Case& c = GetParam();
  MapParams p;
  p.resolution = 0.1;
  p.kernel_length = 0.3;
  p.tile_size = c.tile_size;
  p.method = c.method;
  p.dynamics = c.dynamics;
  p.sensor_height = c.sensor_height;
  p.half_life_s = c.half_life_s;
  std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(p)).value();
  int reported = 0, tiles = 0;
  uint64_t contradicted = 0;
  for (int s = 0; s < 6; ++s) {
    const Eigen::Vector3d origin(1.0 * s, 0.3 * s, 1.2);
    const bool box = s == 2 || s == 3;
    const std::vector<Point3f> points = testing::SampleSurface(
        box ? testing::Surface(WithBox) : testing::Surface(Ground), origin, 6.0, 8000, 7 + s);
    const Snapshot before = Copy(*map);
    Result<ScanReport> report =
        map->IntegrateScan(points, testing::At(origin), false, int64_t{1'000'000'000} * (s + 1));
    ASSERT_TRUE(report.ok()) << report.status().ToString();
    const int blocks =
        ExpectChangesInsideBlocks(before, *map, *report, c.name + " scan " + std::to_string(s));
    if (blocks < 0) return;
    reported += blocks;
    tiles += static_cast<int>(report->changed_tiles.size());
    contradicted += report->contradicted_cells;
  }
  // The box's coming and going exercised free-space evidence.
  if (c.dynamics == Dynamics::kOn) {
    EXPECT_GT(contradicted, 0u) << c.name;
  }
  if (TileBlockShift(c.tile_size) < 0) {
    EXPECT_EQ(reported, kAll * tiles) << "no blocks: whole tiles";
  } else if (c.tile_size == 64 && c.half_life_s == 0) {
    // A 6 m scan in 6.4 m tiles: most tiles it changes, it changes in part. (Forgetting scales
    // a whole tile once it is stamped; 1-cell blocks are smaller than the kernel's reach.)
    EXPECT_LT(reported, kAll * 3 / 4 * tiles) << c.name;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Methods, ChangedBlocksTest,
    ::testing::Values(Case{"bgk_plus_dynamics", Method::kBgkPlus, Dynamics::kOn},
                      Case{"bgk_plus_paper", Method::kBgkPlus, Dynamics::kOff},
                      Case{"bgk_plus_footprint", Method::kBgkPlus, Dynamics::kOn, 1.2},
                      Case{"bgk_plus_forgetting", Method::kBgkPlus, Dynamics::kOn, 0, 2.0},
                      Case{"bgk_ll", Method::kBgkLocalLinear, Dynamics::kOn, 1.2},
                      Case{"bgk_trav", Method::kBgkTrav, Dynamics::kOn},
                      Case{"bgk_obstacle", Method::kBgkObstacle, Dynamics::kOn, 1.2},
                      Case{"baseline", Method::kBaseline, Dynamics::kOn, 1.2},
                      Case{"one_step", Method::kOneStep, Dynamics::kOn},
                      Case{"tile_of_48_cells", Method::kBgkPlus, Dynamics::kOn, 1.2, 0, 48},
                      Case{"tile_of_16_cells", Method::kBgkPlus, Dynamics::kOn, 1.2, 0, 16}),
    [](const ::testing::TestParamInfo<Case>& p) { return p.param.name; });

// The rows of a mask, bit bx of row by for block (bx, by).
std::vector<unsigned> Rows(const TileBlocks& b) {
  std::vector<unsigned> out;
  for (int by = 0; by < kTileBlocksPerSide; ++by) out.push_back(b.Row(by));
  return out;
}

TEST(TileBlocksTest, ABoxMarksTheBlocksItMeets) {
  const int shift = TileBlockShift(64);  // blocks of 4 cells
  EXPECT_EQ(shift, 2);
  std::vector<unsigned> rows(kTileBlocksPerSide, 0);
  rows[0] = 1;
  EXPECT_EQ(Rows(TileBlocksOf(shift, 0, 0, 0, 0)), rows);
  rows[0] = 0;
  rows[1] = rows[2] = 0b110;
  EXPECT_EQ(Rows(TileBlocksOf(shift, 7, 7, 8, 8)), rows);
  rows.assign(kTileBlocksPerSide, 0);
  rows[15] = 1u << 15;
  EXPECT_EQ(Rows(TileBlocksOf(shift, 63, 63, 63, 63)), rows);
  // A row of blocks crossing the words the mask is kept in.
  rows.assign(kTileBlocksPerSide, 0);
  for (int by = 3; by <= 4; ++by) rows[by] = 0xffffu;
  EXPECT_EQ(Rows(TileBlocksOf(shift, 0, 12, 63, 19)), rows);
  EXPECT_EQ(TileBlocksOf(shift, 0, 12, 63, 19).Count(), 32);
  EXPECT_TRUE(TileBlocksOf(shift, 0, 0, 63, 63).IsAll());
  EXPECT_TRUE(TileBlocksOf(shift, 0, 0, 63, 63).Contains(TileBlocksOf(shift, 5, 9, 5, 9)));
  EXPECT_FALSE(TileBlocksOf(shift, 0, 0, 3, 3).Contains(TileBlocksOf(shift, 4, 0, 4, 0)));
  EXPECT_EQ(TileBlockShift(48), -1);
  EXPECT_TRUE(TileBlocksOf(-1, 1, 1, 1, 1).IsAll());
  EXPECT_EQ(TileBlockShift(16), 0);
  EXPECT_EQ(TileBlockShift(8), -1);
  const GridGeometry g(0.1, 64);
  EXPECT_EQ(TileBlockCells(g, {-1, 2}, 2, 1, 3, 2),
            (CellBox{{-64 + 8, 128 + 4}, {-64 + 15, 128 + 11}}));
}

}  // namespace
}  // namespace bgkmap
