// The ground truth of real scans (eval/scan_truth.h) on a hand-made sequence of two scans from
// two poses: flat ground at z = 0 with a 0.3 m step up at x = 1 m, two points per cell (one in
// each scan), plus cells with too little support. The truth must call the step non-traversable
// and the ground far from it traversable, pool the points of both scans under the map's
// observation rule, and leave unknown a cell with one point and a supported cell without three
// known heights within robot_radius.
// Mutations checked once by hand: TruthFromHeights treating a sparse neighbourhood as
// non-traversable in ScanTruthBuilder::Build (SparseNeighbourhood::kNonTraversable) fails
// IsolatedSupportedCellIsUnknown; a support rule of one point (min_points ignored) fails
// OnePointIsNotEnough; the max rule keeping the first scan's value (c.max not updated) fails
// PoolsBothScansUnderTheObservationRule.
#include "bgkmap/eval/scan_truth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace bgkmap::eval {
namespace {

constexpr double kRes = 0.1;
constexpr double kSensorZ = 2.0;

MapParams Params(Observation observation = Observation::kMax) {
  MapParams p;
  p.resolution = kRes;
  p.robot_radius = 0.3;
  p.observation = observation;
  p.dynamics = Dynamics::kOff;
  return p;
}

double Ground(double x) { return x >= 1.0 ? 0.3 : 0.0; }

struct Sequence {
  std::vector<Point3f> a, b;  // sensor frame
  Pose pose_a, pose_b;
};

// Map-frame point -> sensor frame of a sensor at (sx, 0, kSensorZ), no rotation.
Point3f Sensor(double x, double y, double z, double sx) {
  return {static_cast<float>(x - sx), static_cast<float>(y), static_cast<float>(z - kSensorZ)};
}

// Cells ix in [-20, 29], iy in [-10, 9]: scan a holds a point at x = (ix + 0.25) res, scan b
// one at (ix + 0.75) res, both at the cell's y centre. Cell (-15, 5) gets z = 0.04 from scan b
// (0 from scan a). Cell (-50, 0) has one point (scan a); cell (-80, 0), far from every other,
// has two (one per scan); cell (-60, 0) has two points 0.6 m above the sensor, which the
// height filter drops.
Sequence MakeSequence() {
  Sequence s;
  s.pose_a.translation = {0.0, 0.0, kSensorZ};
  s.pose_b.translation = {0.5, 0.0, kSensorZ};
  for (int ix = -20; ix < 30; ++ix) {
    for (int iy = -10; iy < 10; ++iy) {
      const double y = (iy + 0.5) * kRes;
      const double xa = (ix + 0.25) * kRes, xb = (ix + 0.75) * kRes;
      const double bump = (ix == -15 && iy == 5) ? 0.04 : 0.0;
      s.a.push_back(Sensor(xa, y, Ground(xa), 0.0));
      s.b.push_back(Sensor(xb, y, Ground(xb) + bump, 0.5));
    }
  }
  s.a.push_back(Sensor(-4.95, 0.05, 0.0, 0.0));
  s.a.push_back(Sensor(-7.95, 0.05, 0.0, 0.0));
  s.b.push_back(Sensor(-7.95, 0.05, 0.0, 0.5));
  s.a.push_back(Sensor(-5.95, 0.05, kSensorZ + 0.6, 0.0));
  s.b.push_back(Sensor(-5.95, 0.05, kSensorZ + 0.6, 0.5));
  return s;
}

// The value of `layer` at cell c of `r` (NaN outside its box).
float At(const Raster& r, Layer layer, CellIndex c) {
  if (!r.box.Contains(c)) return std::nanf("");
  const std::vector<float>* d = r.Find(layer);
  const int64_t row = r.box.max.y - c.y, col = c.x - r.box.min.x;
  return (*d)[static_cast<size_t>(row * r.cols + col)];
}

CellState StateAt(const Raster& r, CellIndex c) {
  const float v = At(r, Layer::kState, c);
  return std::isnan(v) ? CellState::kUnknown : static_cast<CellState>(static_cast<int>(v));
}

ScanTruthBuilder Built(const MapParams& p) {
  const Sequence s = MakeSequence();
  ScanTruthBuilder builder(p);
  EXPECT_TRUE(builder.AddScan(s.a, s.pose_a).ok());
  EXPECT_TRUE(builder.AddScan(s.b, s.pose_b).ok());
  return builder;
}

TEST(ScanTruthTest, StepIsNonTraversableFlatGroundTraversable) {
  const ScanTruthBuilder builder = Built(Params());
  const Raster truth = builder.Build();
  // The two cells either side of the step, and one within robot_radius of it.
  EXPECT_EQ(StateAt(truth, {9, 0}), CellState::kNonTraversable);
  EXPECT_EQ(StateAt(truth, {10, 0}), CellState::kNonTraversable);
  EXPECT_EQ(StateAt(truth, {7, 0}), CellState::kNonTraversable);
  // Far from it, on both levels.
  EXPECT_EQ(StateAt(truth, {-5, 0}), CellState::kTraversable);
  EXPECT_EQ(StateAt(truth, {25, 0}), CellState::kTraversable);
  EXPECT_FLOAT_EQ(At(truth, Layer::kElevation, {-5, 0}), 0.0f);
  EXPECT_FLOAT_EQ(At(truth, Layer::kElevation, {25, 0}), 0.3f);
  EXPECT_NEAR(At(truth, Layer::kTraversability, {25, 0}), 0.0, 1e-6);
  EXPECT_FLOAT_EQ(At(truth, Layer::kTraversability, {10, 0}), 1.0f);
}

TEST(ScanTruthTest, PoolsBothScansUnderTheObservationRule) {
  // Scan a saw 0 in cell (-15, 5), scan b 0.04 (from another pose).
  const Raster max_truth = Built(Params(Observation::kMax)).Build();
  EXPECT_NEAR(At(max_truth, Layer::kElevation, {-15, 5}), 0.04, 1e-6);
  const Raster mean_truth = Built(Params(Observation::kMean)).Build();
  EXPECT_NEAR(At(mean_truth, Layer::kElevation, {-15, 5}), 0.02, 1e-6);
}

TEST(ScanTruthTest, OnePointIsNotEnough) {
  const ScanTruthBuilder builder = Built(Params());
  EXPECT_TRUE(std::isnan(builder.Surface().at({-50, 0})));
  EXPECT_EQ(StateAt(builder.Build(), {-50, 0}), CellState::kUnknown);
  // With a support of one point the cell is on the surface (but still unjudged: no neighbours).
  ScanTruthOptions one;
  one.min_points = 1;
  const Sequence s = MakeSequence();
  ScanTruthBuilder loose(Params(), one);
  ASSERT_TRUE(loose.AddScan(s.a, s.pose_a).ok());
  ASSERT_TRUE(loose.AddScan(s.b, s.pose_b).ok());
  EXPECT_FLOAT_EQ(static_cast<float>(loose.Surface().at({-50, 0})), 0.0f);
}

TEST(ScanTruthTest, IsolatedSupportedCellIsUnknown) {
  const ScanTruthBuilder builder = Built(Params());
  // Two points, so on the surface, but no known neighbour within robot_radius.
  EXPECT_FLOAT_EQ(static_cast<float>(builder.Surface().at({-80, 0})), 0.0f);
  const Raster truth = builder.Build();
  EXPECT_EQ(StateAt(truth, {-80, 0}), CellState::kUnknown);
  EXPECT_TRUE(std::isnan(At(truth, Layer::kElevation, {-80, 0})));
}

TEST(ScanTruthTest, MappingFiltersApplyAndCountsAddUp) {
  const ScanTruthBuilder builder = Built(Params());
  EXPECT_TRUE(std::isnan(builder.Surface().at({-60, 0})));  // above max_height_above_sensor
  const Raster truth = builder.Build();
  const ScanTruthStats s = builder.Stats(truth);
  EXPECT_EQ(s.scans, 2u);
  EXPECT_EQ(s.points_input, 2u * 50 * 20 + 5);
  EXPECT_EQ(s.points_kept, 2u * 50 * 20 + 3);
  EXPECT_EQ(s.observed_cells, 50 * 20 + 2);
  EXPECT_EQ(s.supported_cells, 50 * 20 + 1);
  EXPECT_EQ(s.judged_cells, 50 * 20);
  EXPECT_EQ(s.traversable_cells + s.non_traversable_cells, s.judged_cells);
  // Non-traversable: the cells within robot_radius (3 cells) of the step, both sides, all rows.
  EXPECT_EQ(s.non_traversable_cells, 6 * 20);
}

TEST(ScanTruthTest, InvalidPoseAddsNothing) {
  ScanTruthBuilder builder(Params());
  Pose bad;
  bad.rotation(0, 0) = 2.0;
  const std::vector<Point3f> points = {{1.0f, 1.0f, -2.0f}};
  EXPECT_FALSE(builder.AddScan(points, bad).ok());
  const ScanTruthStats s = builder.Stats(builder.Build());
  EXPECT_EQ(s.scans, 0u);
  EXPECT_EQ(s.observed_cells, 0);
}

}  // namespace
}  // namespace bgkmap::eval
