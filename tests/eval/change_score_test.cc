// The change scores on hand-made cells (eval/change_score.h): which cells a change is judged on,
// and when a map's cell is stale (removed object) or missed (appeared object).
// Mutation checked once: the elevation rule reversed (to_old > to_new) fails the second test.
#include "bgkmap/eval/change_score.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace bgkmap::eval {
namespace {

constexpr float kNaN = NAN;
constexpr auto kT = CellState::kTraversable;
constexpr auto kN = CellState::kNonTraversable;

// A 4 x 1 truth raster over cells (0..3, 0): elevations and states, NaN = not in the region.
Raster Row(std::vector<float> z, std::vector<float> state) {
  Raster r;
  r.box = {{0, 0}, {3, 0}};
  r.cols = 4;
  r.rows = 1;
  r.resolution = 0.1;
  r.layers = {Layer::kElevation, Layer::kState};
  r.data = {std::move(z), std::move(state)};
  return r;
}

float S(CellState s) { return static_cast<float>(static_cast<int>(s)); }

TEST(ChangeScoreTest, JudgedCellsAreTheOnesTheChangeChangedAndTheTruthSees) {
  // Cell 0: a box's top (1 m) that became ground; 1: the step at its edge, blocked then free;
  // 2: ground that stayed ground; 3: outside the region.
  const Raster before = Row({1.0f, 0.0f, 0.0f, kNaN}, {S(kT), S(kN), S(kT), kNaN});
  const Raster after = Row({0.0f, 0.0f, 0.0f, kNaN}, {S(kT), S(kT), S(kT), kNaN});
  const auto all = [](CellIndex) { return true; };
  std::vector<ChangedCell> removed = JudgedCells(before, after, ChangeKind::kRemoved, 1.0, all);
  ASSERT_EQ(removed.size(), 2u);
  EXPECT_EQ(removed[0].cell.x, 0);
  EXPECT_TRUE(removed[0].moved);
  EXPECT_EQ(removed[1].cell.x, 1);
  EXPECT_FALSE(removed[1].moved);
  // A top only 0.4 m above the ground is no move for a 1 m object (half its height).
  const Raster low = Row({0.4f, 0.0f, 0.0f, kNaN}, {S(kT), S(kN), S(kT), kNaN});
  EXPECT_EQ(JudgedCells(low, after, ChangeKind::kRemoved, 1.0, all).size(), 1u);
  // Cells the truth scans do not see are not judged.
  EXPECT_EQ(
      JudgedCells(before, after, ChangeKind::kRemoved, 1.0, [](CellIndex c) { return c.x != 0; })
          .size(),
      1u);
  // The same change backwards is an appearance: only the cell that became non-traversable.
  const std::vector<ChangedCell> appeared =
      JudgedCells(after, before, ChangeKind::kAppeared, 1.0, all);
  ASSERT_EQ(appeared.size(), 1u);
  EXPECT_EQ(appeared[0].cell.x, 1);
}

// A map over cells (0..3, 0) from one point each at the given heights (NaN: no point, unknown).
std::unique_ptr<TerrainMap> MapOf(const std::vector<float>& z) {
  MapParams p;
  p.method = Method::kBaseline;  // raw elevation: no inference into the other cells
  auto map = std::move(TerrainMap::Create(p)).value();
  std::vector<Point3f> points;
  for (size_t i = 0; i < z.size(); ++i) {
    if (!std::isnan(z[i])) points.push_back({(i + 0.5f) * 0.1f, 0.05f, z[i]});
  }
  EXPECT_TRUE(map->IntegrateScan(points, Pose{}, /*frame_is_map=*/true).ok());
  return map;
}

TEST(ChangeScoreTest, StaleIsStillHighOrStillBlockedAndMissedIncludesUnknown) {
  ChangedCell top{{0, 0}, 1.0f, 0.0f, kT, kT, /*moved=*/true};
  ChangedCell edge{{3, 0}, 0.0f, 0.0f, kN, kT, /*moved=*/false};
  const std::vector<ChangedCell> removed = {top, edge};
  // The map still has the top at 0.9 m: stale (nearer 1 m than 0 m); the edge cell is unknown.
  auto map = MapOf({0.9f, kNaN, kNaN, kNaN});
  ChangeCounts c = ScoreChange(*map, removed, ChangeKind::kRemoved);
  EXPECT_EQ(c.judged, 2);
  EXPECT_EQ(c.wrong, 1);
  EXPECT_EQ(c.unknown, 1);
  EXPECT_DOUBLE_EQ(c.rate(), 0.5);
  // Down to 0.4 m: nearer the new ground, no longer stale.
  map = MapOf({0.4f, kNaN, kNaN, kNaN});
  EXPECT_EQ(ScoreChange(*map, removed, ChangeKind::kRemoved).wrong, 0);

  // An appeared object's cell the map does not know is missed.
  const std::vector<ChangedCell> appeared = {{{1, 0}, 0.0f, 0.0f, kT, kN, false}};
  map = MapOf({0.0f, kNaN, kNaN, kNaN});
  c = ScoreChange(*map, appeared, ChangeKind::kAppeared);
  EXPECT_EQ(c.wrong, 1);
  EXPECT_EQ(c.unknown, 1);
  EXPECT_TRUE(std::isnan(ChangeCounts{}.rate()));
}

}  // namespace
}  // namespace bgkmap::eval
