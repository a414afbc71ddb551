// Where the map is cut into bands of whole tiles (core/band_cut.h).
#include "bgkmap/core/band_cut.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

namespace bgkmap {
namespace {

// The work of the band [lo, hi): the cells within `halo` of it.
int64_t Work(const std::vector<int64_t>& cells, int64_t first, int halo, int64_t lo, int64_t hi) {
  int64_t n = 0;
  for (size_t i = 0; i < cells.size(); ++i) {
    const int64_t v = first + static_cast<int64_t>(i);
    if (v >= lo - halo && v < hi + halo) n += cells[i];
  }
  return n;
}

int64_t LargestWork(const std::vector<int64_t>& cells, int64_t first, int halo,
                    const std::vector<int64_t>& borders) {
  constexpr int64_t kLow = std::numeric_limits<int32_t>::min(),
                    kHigh = std::numeric_limits<int32_t>::max();
  int64_t worst = 0, lo = kLow;
  for (const int64_t b : borders) {
    worst = std::max(worst, Work(cells, first, halo, lo, b));
    lo = b;
  }
  return std::max(worst, Work(cells, first, halo, lo, kHigh));
}

TEST(BandCutTest, NoCutForOneBandOrNoCells) {
  EXPECT_TRUE(CutBorders({5, 5, 5, 5, 5, 5, 5, 5}, 0, 4, 0, 1).empty());
  EXPECT_TRUE(CutBorders({}, 0, 4, 0, 2).empty());
}

// The fault this replaced: the tile border below the median cell. The median falls on the dense
// column 7, so the border went to 4 (4 cells against 18); the least work is the border at 8.
TEST(BandCutTest, DenseColumnBelowTheBorderGoesToTheFirstBand) {
  const std::vector<int64_t> cells = {1, 1, 1, 1, 1, 1, 1, 10, 1, 1, 1, 1};
  EXPECT_EQ(CutBorders(cells, 0, 4, 0, 2), std::vector<int64_t>{8});
  // The same, 1000 cells to the left of the origin (negative coordinates, floor division).
  EXPECT_EQ(CutBorders(cells, -1000, 4, 0, 2), std::vector<int64_t>{-992});
}

// A halo as wide as the map: each band would integrate everything, so one band does.
TEST(BandCutTest, NoCutWhenTheHaloCoversTheMap) {
  EXPECT_TRUE(CutBorders({3, 3, 3, 3, 3, 3, 3, 3}, 0, 4, 4, 2).empty());
}

// Against every cut at tile borders: the least largest work, then the fewest bands; the borders
// increase, are tile borders, and lie strictly inside the cells' extent.
TEST(BandCutTest, LeastLargestWorkAgainstEveryCut) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 300; ++trial) {
    const int tile = 1 + static_cast<int>(rng() % 4);
    const int halo = static_cast<int>(rng() % 4);
    const int bands = 2 + static_cast<int>(rng() % 3);
    const int64_t first = static_cast<int64_t>(rng() % 21) - 10;
    std::vector<int64_t> cells(1 + rng() % 16);
    for (int64_t& c : cells) c = rng() % 3 == 0 ? 0 : rng() % 20;
    const int64_t end = first + static_cast<int64_t>(cells.size());
    std::vector<int64_t> candidates;
    for (int64_t t = first + 1; t < end; ++t) {
      if (t % tile == 0) candidates.push_back(t);
    }
    // Every subset of the candidates with fewer than `bands` borders.
    int64_t best = std::numeric_limits<int64_t>::max();
    size_t fewest = 0;
    for (uint32_t mask = 0; mask < (1u << candidates.size()); ++mask) {
      std::vector<int64_t> borders;
      for (size_t i = 0; i < candidates.size(); ++i) {
        if (mask & (1u << i)) borders.push_back(candidates[i]);
      }
      if (static_cast<int>(borders.size()) >= bands) continue;
      const int64_t work = LargestWork(cells, first, halo, borders);
      if (work < best || (work == best && borders.size() < fewest)) {
        best = work;
        fewest = borders.size();
      }
    }
    const std::vector<int64_t> cut = CutBorders(cells, first, tile, halo, bands);
    SCOPED_TRACE(::testing::Message() << "trial " << trial << " tile " << tile << " halo " << halo
                                      << " bands " << bands << " first " << first);
    EXPECT_EQ(LargestWork(cells, first, halo, cut), best);
    EXPECT_EQ(cut.size(), fewest);
    EXPECT_TRUE(std::is_sorted(cut.begin(), cut.end()));
    EXPECT_EQ(std::adjacent_find(cut.begin(), cut.end()), cut.end());
    for (const int64_t b : cut) {
      EXPECT_EQ(b % tile, 0);
      EXPECT_GT(b, first);
      EXPECT_LT(b, end);
    }
  }
}

}  // namespace
}  // namespace bgkmap
