// Tile::Known() (one pass: count and local box of the known cells) against a cell-by-cell count
// with IsKnown(), on random patterns where cells are known by weight, by pseudo-counts or both.
#include <gtest/gtest.h>

#include <random>

#include "bgkmap/core/tile.h"
#include "bgkmap/core/tile_summary.h"

namespace bgkmap {
namespace {

TEST(TileKnownTest, MatchesACellByCellCount) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = trial % 3 == 0 ? 4 : 64;
    Tile t(n);
    const int density = 1 + static_cast<int>(rng() % 50);  // 1: every cell
    for (int i = 0; i < t.cell_count(); ++i) {
      if (rng() % density != 0) continue;
      switch (rng() % 3) {
        case 0:
          t.w()[i] = 0.5;
          break;
        case 1:
          t.a()[i] = 0.25f;
          break;
        default:
          t.b()[i] = 0.75f;
          t.w()[i] = 2.0;
          break;
      }
    }
    int count = 0;
    CellBox box;
    for (int i = 0; i < t.cell_count(); ++i) {
      if (!t.IsKnown(i)) continue;
      ++count;
      box.Extend({i % n, i / n});
    }
    const Tile::KnownCells known = t.Known();
    ASSERT_EQ(known.count, count) << "trial " << trial;
    ASSERT_EQ(known.local_box, box) << "trial " << trial;
    const TileSummary s = SummarizeTile(GridGeometry(0.1, n), {-2, 3}, &t);
    EXPECT_EQ(s.known_cells, static_cast<uint32_t>(count));
    if (count > 0) {
      EXPECT_EQ(s.known_box.min, (CellIndex{-2 * n + box.min.x, 3 * n + box.min.y}));
      EXPECT_EQ(s.known_box.max, (CellIndex{-2 * n + box.max.x, 3 * n + box.max.y}));
    } else {
      EXPECT_TRUE(s.known_box.empty());
    }
  }
  EXPECT_EQ(Tile(8).Known().count, 0);
  EXPECT_TRUE(Tile(8).Known().local_box.empty());
}

}  // namespace
}  // namespace bgkmap
