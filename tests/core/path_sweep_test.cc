// The path rule of docs/semantics.md ("Path checks"): placements along the segments between
// poses, no footprint point moving more than a cell between two, each judged as a pose is.
#include "bgkmap/core/path_sweep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <set>

namespace bgkmap {
namespace {

const GridGeometry kGrid(0.1, 64);

Footprint Disk(double radius) {
  Footprint f;
  f.radius = radius;
  return f;
}

TEST(PathSweepTest, StepsKeepEveryFootprintPointWithinACell) {
  // Translation: a distance of exactly k cells is k steps, not k + 1 (the tolerance).
  EXPECT_EQ(SegmentSteps({0, 0, 0}, {1.0, 0, 0}, Disk(0.3), 0.1), 10u);
  EXPECT_EQ(SegmentSteps({0, 0, 0}, {1.05, 0, 0}, Disk(0.3), 0.1), 11u);
  EXPECT_EQ(SegmentSteps({-8, -2, 0}, {8, 2, 0}, Disk(0.3), 0.1), 165u);  // 16.49 m
  // Two poses in one place: one step, no sample between them.
  EXPECT_EQ(SegmentSteps({1, 1, 0}, {1, 1, 0}, Disk(0.3), 0.1), 1u);
  // Turning in place moves a disk nowhere, a polygon's corners by the turn times its reach.
  EXPECT_EQ(SegmentSteps({0, 0, 0}, {0, 0, std::numbers::pi / 2}, Disk(0.3), 0.1), 1u);
  Footprint box;
  box.polygon = {{-0.3, -0.4}, {0.3, -0.4}, {0.3, 0.4}, {-0.3, 0.4}};              // reach 0.5
  EXPECT_EQ(SegmentSteps({0, 0, 0}, {0, 0, std::numbers::pi / 2}, box, 0.1), 8u);  // 0.785 m
  // The short way round: from 3 to -3 rad is a turn of 2 pi - 6 = 0.283 rad.
  EXPECT_EQ(SegmentSteps({0, 0, 3.0}, {0, 0, -3.0}, box, 0.1), 2u);
}

TEST(PathSweepTest, PlacementsInPathOrderWithInterpolatedHeading) {
  const std::vector<Pose2> poses = {{0, 0, 3.0}, {0.25, 0, -3.0}, {0.25, 0, -3.0}};
  Footprint box;
  box.polygon = {{-0.1, -0.1}, {0.1, -0.1}, {0.1, 0.1}, {-0.1, 0.1}};
  const std::vector<PathPlacement> p = PathPlacements(poses, box, 0.1);
  // 0.25 m + 0.283 rad x 0.141 m = 0.29 m: 3 steps, 2 samples; the last segment has none.
  ASSERT_EQ(p.size(), 5u);
  EXPECT_EQ(CountPlacements(poses, box, 0.1), 5.0);
  EXPECT_EQ(p[0].segment, 0u);
  EXPECT_EQ(p[0].t, 0.0);
  EXPECT_EQ(p[1].segment, 0u);
  EXPECT_DOUBLE_EQ(p[1].t, 1.0 / 3);
  EXPECT_DOUBLE_EQ(p[1].pose.x, 0.25 / 3);
  EXPECT_NEAR(p[1].pose.yaw, 3.0 + (2 * std::numbers::pi - 6.0) / 3, 1e-12);  // through pi
  EXPECT_EQ(p[2].segment, 0u);
  EXPECT_EQ(p[3].segment, 1u);
  EXPECT_EQ(p[3].t, 0.0);
  EXPECT_EQ(p[4].segment, 2u);
  EXPECT_EQ(p[4].t, 0.0);
}

TEST(PathSweepTest, SweptCellsAreTheUnionOfThePlacementsFootprints) {
  const std::vector<Pose2> poses = {{-3, -1, 0}, {2, 1.5, 1}, {2.2, -4, -2}};
  Footprint box;
  box.polygon = {{-0.5, -0.3}, {0.6, -0.3}, {0.6, 0.3}, {-0.5, 0.3}};
  for (const Footprint& f : {Disk(0.45), box}) {
    const std::vector<PathPlacement> p = PathPlacements(poses, f, 0.1);
    std::set<CellIndex> want;
    for (const PathPlacement& q : p) {
      for (CellIndex c : FootprintCells(kGrid, f, q.pose)) want.insert(c);
    }
    const std::vector<CellIndex> got = SweptCells(kGrid, f, p);
    EXPECT_EQ(got, std::vector<CellIndex>(want.begin(), want.end()));
  }
}

// Known, safe ground everywhere but `holes`.
std::vector<CellEstimate> GroundWithHoles(std::span<const CellIndex> cells,
                                          const std::set<CellIndex>& holes) {
  std::vector<CellEstimate> out(cells.size());
  for (size_t i = 0; i < cells.size(); ++i) {
    if (holes.count(cells[i])) {
      out[i].traversability = std::nanf("");
      out[i].traversability_variance = std::nanf("");
    } else {
      out[i].traversability = 0.1f;
      out[i].traversability_variance = 0.01f;
    }
  }
  return out;
}

TEST(PathSweepTest, AnUnknownCellBetweenSafePosesMakesThePathUnsafeThere) {
  const std::vector<Pose2> poses = {{-8, -2, 0}, {8, 2, 0}, {8, 2, 1}};
  const Footprint disk = Disk(0.3);
  const PathThresholds thresholds{0.5, 0.1, 0.0};
  const std::vector<PathPlacement> p = PathPlacements(poses, disk, 0.1);
  const std::vector<CellIndex> cells = SweptCells(kGrid, disk, p);

  const PathVerdict clear =
      JudgePath(kGrid, disk, p, cells, GroundWithHoles(cells, {}), thresholds);
  EXPECT_TRUE(clear.safe);
  ASSERT_EQ(clear.poses.size(), 3u);
  ASSERT_EQ(clear.segments.size(), 2u);
  EXPECT_EQ(clear.segments[0].placement_count, 164u);
  EXPECT_EQ(clear.segments[1].placement_count, 0u);  // a disk turning in place
  EXPECT_FALSE(clear.first_unsafe);

  // The cell under (0, 0): far from both poses, under the segment.
  const CellIndex hole = kGrid.CellAt(0.0, 0.0);
  const PathVerdict holed =
      JudgePath(kGrid, disk, p, cells, GroundWithHoles(cells, {hole}), thresholds);
  EXPECT_FALSE(holed.safe);
  EXPECT_TRUE(holed.poses[0].safe);
  EXPECT_TRUE(holed.poses[1].safe);
  EXPECT_FALSE(holed.segments[0].safe);
  EXPECT_TRUE(holed.segments[1].safe);
  ASSERT_TRUE(holed.first_unsafe);
  const PlacementCheck& first = *holed.first_unsafe;
  EXPECT_EQ(first.where.segment, 0u);
  EXPECT_FALSE(first.check.safe);
  EXPECT_GT(first.check.unknown_fraction, 0.0f);
  // The first placement whose disk reaches the hole's centre, and the one before does not.
  const double hx = kGrid.CellCenterX(hole.x), hy = kGrid.CellCenterY(hole.y);
  EXPECT_TRUE(WithinRadius(first.where.pose.x - hx, first.where.pose.y - hy, 0.3));
  const auto before =
      std::find_if(p.begin(), p.end(),
                   [&](const PathPlacement& q) {
                     return q.t == first.where.t && q.segment == first.where.segment;
                   }) -
      1;
  EXPECT_FALSE(WithinRadius(before->pose.x - hx, before->pose.y - hy, 0.3));
  EXPECT_EQ(holed.segments[0].first_unsafe->where.t, first.where.t);
}

TEST(PathSweepTest, AnUnsafePoseComesBeforeItsSegment) {
  const std::vector<Pose2> poses = {{0, 0, 0}, {2, 0, 0}};
  const Footprint disk = Disk(0.2);
  const std::vector<PathPlacement> p = PathPlacements(poses, disk, 0.1);
  const std::vector<CellIndex> cells = SweptCells(kGrid, disk, p);
  const PathVerdict v = JudgePath(
      kGrid, disk, p, cells, GroundWithHoles(cells, {kGrid.CellAt(0.05, 0.05)}), {0.5, 0.1, 0});
  ASSERT_TRUE(v.first_unsafe);
  EXPECT_EQ(v.first_unsafe->where.t, 0.0);  // the pose itself
  EXPECT_EQ(v.first_unsafe->where.segment, 0u);
  EXPECT_FALSE(v.poses[0].safe);
}

}  // namespace
}  // namespace bgkmap
