// The map's one rule for which cells a shape covers (cell_shapes.h), the half-open region rule
// (GridGeometry::CellsOfInterval), and a path check's footprint and verdict (path_check.h).
#include "bgkmap/core/cell_shapes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "bgkmap/core/path_check.h"

namespace bgkmap {
namespace {

bool Has(const std::vector<CellIndex>& cells, int x, int y) {
  return std::find(cells.begin(), cells.end(), CellIndex{x, y}) != cells.end();
}

TEST(CellsInDiskTest, KeepsCellCentresExactlyOnTheRadius) {
  const GridGeometry g(0.1, 64);
  // Centre on a cell centre (0.05, 0.05): the cell 3 east is 0.3 m away, on the radius. Without
  // the tolerance 0.3 * 0.3 rounds below (0.35 - 0.05)^2 and it would be lost.
  const std::vector<CellIndex> cells = CellsInDisk(g, {0.05, 0.05}, 0.3);
  EXPECT_EQ(cells.size(), 29u);  // the same disk as DiskOffsets(0.3, 0.1)
  EXPECT_TRUE(Has(cells, 3, 0));
  EXPECT_TRUE(Has(cells, -3, 0));
  EXPECT_TRUE(Has(cells, 0, 3));
  EXPECT_FALSE(Has(cells, 3, 1));
  EXPECT_TRUE(std::is_sorted(cells.begin(), cells.end()));
}

TEST(CellsInDiskTest, ADiskBetweenCentresCoversTheCellUnderIt) {
  const GridGeometry g(1.0, 16);
  const std::vector<CellIndex> cells = CellsInDisk(g, {-2.9, 4.1}, 0.2);
  ASSERT_EQ(cells.size(), 1u);
  EXPECT_EQ(cells[0], (CellIndex{-3, 4}));
}

TEST(CellsInDiskTest, MatchesDiskOffsetsAroundEveryCellCentre) {
  const GridGeometry g(0.2, 8);
  const std::vector<CellIndex> offsets = DiskOffsets(0.7, 0.2);
  ASSERT_FALSE(offsets.empty());
  for (const CellIndex c : {CellIndex{0, 0}, CellIndex{-5, 7}, CellIndex{13, -2}}) {
    std::vector<CellIndex> expected;
    for (const CellIndex& o : offsets) expected.push_back({c.x + o.x, c.y + o.y});
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(CellsInDisk(g, {g.CellCenterX(c.x), g.CellCenterY(c.y)}, 0.7), expected);
  }
}

TEST(CellsInPolygonTest, EvenOddRuleOverCellCentres) {
  const GridGeometry g(1.0, 16);
  // A 3 x 2 m rectangle from (0, 0): the centres (0.5 .. 2.5, 0.5 .. 1.5).
  const std::vector<Point2> rect = {{0, 0}, {3, 0}, {3, 2}, {0, 2}};
  const std::vector<CellIndex> cells = CellsInPolygon(g, rect, {1.5, 1.0});
  EXPECT_EQ(cells.size(), 6u);
  EXPECT_TRUE(Has(cells, 2, 1));
  EXPECT_FALSE(Has(cells, 3, 1));
  // A sliver between centres covers the cell under its anchor.
  const std::vector<Point2> sliver = {{0.6, 0.6}, {0.9, 0.6}, {0.9, 0.9}};
  EXPECT_EQ(CellsInPolygon(g, sliver, {0.7, 0.7}), (std::vector<CellIndex>{{0, 0}}));
}

TEST(GridRegionTest, HalfOpenWithUpperEdgesSnappedToBorders) {
  const GridGeometry g(0.1, 64);
  const CellBox box = g.CellsOfRegion(-10, 0, 200, 0.35);
  // -10 / 0.1 = -100.00000000000001 and 200 / 0.1 = 2000.0000000000002: no extra cell.
  EXPECT_EQ(box.min, (CellIndex{-100, 0}));
  EXPECT_EQ(box.max, (CellIndex{1999, 3}));
  // A region thinner than a cell still has one.
  const GridGeometry::CellRange r = g.CellsOfInterval(0.31, 0.32);
  EXPECT_EQ(r.first, 3);
  EXPECT_EQ(r.last, 3);
}

TEST(FootprintCellsTest, APolygonTurnsWithThePose) {
  const GridGeometry g(0.5, 16);
  Footprint f;
  f.polygon = {{-0.25, -1.0}, {0.25, -1.0}, {0.25, 1.0}, {-0.25, 1.0}};  // long across
  EXPECT_DOUBLE_EQ(f.Reach(), std::hypot(0.25, 1.0));
  const std::vector<CellIndex> across = FootprintCells(g, f, {0.1, 0.1, 0.0});
  const std::vector<CellIndex> along = FootprintCells(g, f, {0.1, 0.1, M_PI / 2});
  EXPECT_EQ(across.size(), 4u);  // one column, four rows
  EXPECT_EQ(along.size(), 4u);   // one row, four columns
  EXPECT_TRUE(Has(across, 0, 1) && Has(across, 0, -2));
  EXPECT_TRUE(Has(along, 1, 0) && Has(along, -2, 0));
}

CellEstimate Cell(float trav, float var) {
  CellEstimate e{};
  e.traversability = trav;
  e.traversability_variance = var;
  return e;
}

TEST(JudgeFootprintTest, WorstCellDecidesAndUnknownCounts) {
  const PathThresholds t{0.5, 0.05, 0.25};
  const std::vector<CellEstimate> cells = {Cell(0.2, 0.01), Cell(0.4, 0.02), Cell(0.4, 0.03),
                                           Cell(NAN, NAN)};
  const PoseCheck c = JudgeFootprint(cells, t);
  EXPECT_FLOAT_EQ(c.worst_traversability, 0.4f);
  EXPECT_FLOAT_EQ(c.worst_traversability_variance, 0.03f);  // ties: the higher variance
  EXPECT_FLOAT_EQ(c.unknown_fraction, 0.25f);
  EXPECT_EQ(c.cell_count, 4u);
  EXPECT_TRUE(c.safe);
  EXPECT_FALSE(JudgeFootprint(cells, {0.4, 0.05, 0.25}).safe);   // worst must be below
  EXPECT_FALSE(JudgeFootprint(cells, {0.5, 0.025, 0.25}).safe);  // its variance too
  EXPECT_FALSE(JudgeFootprint(cells, {0.5, 0.05, 0.2}).safe);    // too much unknown
  const std::vector<CellEstimate> unknown = {Cell(NAN, NAN)};
  EXPECT_FALSE(JudgeFootprint(unknown, {0.5, 0.05, 1.0}).safe);  // nothing known: not safe
}

}  // namespace
}  // namespace bgkmap
