// The truth that needs no survey (eval/drive_score.h), pinned on hand-made cases: which cells a
// footprint drives over (disc, swept between poses; a box turned to the heading with the sensor
// off its centre), why a cell is blocked (condition by condition, and always exactly when the
// map's own state rule blocks it), the driven cells' shares on a hand-filled map, and two maps
// compared cell by cell. Mutation checked by hand: the footprint placed at the poses only, not
// swept between them, fails TheFootprintIsSweptBetweenPoses.
#include "bgkmap/eval/drive_score.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace bgkmap::eval {
namespace {

Pose At(double x, double y, double z = 0.0, double yaw = 0.0) {
  Pose p;
  p.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation = {x, y, z};
  return p;
}

bool Has(const std::vector<DrivenCell>& cells, CellIndex c) {
  return std::any_of(cells.begin(), cells.end(), [&](const DrivenCell& d) { return d.cell == c; });
}

const GridGeometry kGrid(0.1, 64);

TEST(DrivenCellsTest, ADiscCoversTheCellCentresWithinItsRadiusBoundaryIncluded) {
  const std::vector<Pose> poses = {At(0.05, 0.05, 2.0)};  // on the centre of cell (0, 0)
  const std::vector<DrivenCell> cells = DrivenCells(kGrid, poses, Footprint::Disc(0.1), 1.5);
  ASSERT_EQ(cells.size(), 5u);  // the cell and its four neighbours, exactly 0.1 m away
  for (CellIndex c :
       {CellIndex{0, 0}, CellIndex{1, 0}, CellIndex{-1, 0}, CellIndex{0, 1}, CellIndex{0, -1}}) {
    EXPECT_TRUE(Has(cells, c)) << c.x << "," << c.y;
  }
  EXPECT_TRUE(
      std::is_sorted(cells.begin(), cells.end(),
                     [](const DrivenCell& a, const DrivenCell& b) { return a.cell < b.cell; }));
  for (const DrivenCell& d : cells) EXPECT_DOUBLE_EQ(d.ground_z, 0.5);  // 2.0 - 1.5
  // Without a sensor height the ground's height is unknown.
  for (const DrivenCell& d : DrivenCells(kGrid, poses, Footprint::Disc(0.1), 0.0)) {
    EXPECT_TRUE(std::isnan(d.ground_z));
  }
}

TEST(DrivenCellsTest, TheFootprintIsSweptBetweenPoses) {
  // Two poses 1 m apart along a row of cell centres: the strip between them is driven too.
  const std::vector<Pose> poses = {At(0.05, 0.05), At(1.05, 0.05)};
  const std::vector<DrivenCell> cells = DrivenCells(kGrid, poses, Footprint::Disc(0.1), 0.0);
  // Rows -1, 0, 1 over columns 0..10 (33), plus the two end caps (-1, 0) and (11, 0).
  EXPECT_EQ(cells.size(), 35u);
  EXPECT_TRUE(Has(cells, {5, 1}));
  EXPECT_TRUE(Has(cells, {11, 0}));
  EXPECT_FALSE(Has(cells, {5, 2}));
  EXPECT_FALSE(Has(cells, {12, 0}));
}

TEST(DrivenCellsTest, ABoxTurnsWithTheHeadingAndSitsBehindASensorMountedAhead) {
  // Heading +y; a box 1.0 m long and 0.2 m wide whose sensor is 0.4 m ahead of its centre: the
  // box spans 0.9 m behind the sensor to 0.1 m ahead of it, 0.1 m to either side.
  const double yaw = std::numbers::pi / 2;
  const std::vector<Pose> poses = {At(0.05, 0.05, 0.0, yaw)};
  const Footprint box = Footprint::Box(1.0, 0.2, 0.4, 0.0);
  const std::vector<DrivenCell> cells = DrivenCells(kGrid, poses, box, 0.0);
  EXPECT_TRUE(Has(cells, {0, 0}));
  EXPECT_TRUE(Has(cells, {0, 1}));   // 0.1 m ahead: the box's front edge
  EXPECT_FALSE(Has(cells, {0, 2}));  // 0.2 m ahead
  EXPECT_TRUE(Has(cells, {0, -9}));  // 0.9 m behind: its rear edge
  EXPECT_FALSE(Has(cells, {0, -10}));
  EXPECT_TRUE(Has(cells, {1, -5}));  // 0.1 m to the right
  EXPECT_FALSE(Has(cells, {2, -5}));
  EXPECT_EQ(cells.size(), 33u);  // 11 rows of 3 cells
  // Heading +x: the same box lies along x.
  const std::vector<DrivenCell> east = DrivenCells(kGrid, {{At(0.05, 0.05)}}, box, 0.0);
  EXPECT_TRUE(Has(east, {-9, 0}));
  EXPECT_FALSE(Has(east, {0, -9}));
}

TEST(FootprintTest, ReachBoundsEveryPointInside) {
  const Footprint box = Footprint::Box(4.0, 2.0, 1.0, 0.0);
  EXPECT_DOUBLE_EQ(box.Reach(), std::hypot(3.0, 1.0));
  EXPECT_TRUE(box.Contains(-3.0, 1.0));
  EXPECT_FALSE(box.Contains(1.01, 0.0));
  EXPECT_DOUBLE_EQ(Footprint::Disc(0.8).Reach(), 0.8);
}

MapParams Params(Method method = Method::kBgkPlus, Dynamics dynamics = Dynamics::kOn) {
  MapParams p;
  p.method = method;
  p.dynamics = dynamics;
  return p;
}

TEST(BlockReasonsTest, EachConditionOfTheStateRule) {
  const MapParams p = Params();
  // A flat, well observed cell: traversable.
  EXPECT_EQ(BlockReasons(p, 10.0, 5.0, 2.5, 0.5f, 9.5f), 0);
  // Unknown: nothing to explain.
  EXPECT_EQ(BlockReasons(p, 0.0, 0.0, 0.0, 0.0f, 0.0f), 0);
  // Elevation but no traversability evidence.
  EXPECT_EQ(BlockReasons(p, 1.0, 0.5, 0.25, 0.0f, 0.0f), kNoValue);
  // Evidence of a step: the mean.
  EXPECT_EQ(BlockReasons(p, 10.0, 5.0, 2.5, 8.0f, 2.0f), kHighMean);
  // Little evidence, all of it traversable: the variance (mean 0.14, variance 0.08).
  EXPECT_EQ(BlockReasons(p, 1.0, 0.5, 0.25, 0.05f, 0.3f), kHighVariance);
  // Observations 1 m apart (D = 0.25 m^2 > 0.15^2), traversability evidence fine.
  EXPECT_EQ(BlockReasons(p, 2.0, 1.0, 1.0, 0.5f, 9.5f), kDisagreement);
  // Both mean and disagreement.
  EXPECT_EQ(BlockReasons(p, 2.0, 1.0, 1.0, 8.0f, 2.0f), kHighMean | kDisagreement);
  // Without dynamics the disagreement is no rule.
  EXPECT_EQ(BlockReasons(Params(Method::kBgkPlus, Dynamics::kOff), 2.0, 1.0, 1.0, 0.5f, 9.5f), 0);
}

TEST(BlockReasonsTest, BlockedExactlyWhenTheMapsStateRuleBlocks) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (Method method : {Method::kBgkPlus, Method::kBaseline, Method::kOneStep, Method::kBgkObstacle,
                        Method::kBgkTrav}) {
    for (Dynamics dynamics : {Dynamics::kOn, Dynamics::kOff}) {
      const MapParams p = Params(method, dynamics);
      int blocked = 0, traversable = 0;
      for (int i = 0; i < 4000; ++i) {
        const double w = u(rng) < 0.1 ? 0.0 : 5.0 * u(rng);
        const double mean = u(rng), spread = 0.3 * u(rng);
        const double s = w * mean, q = w * (mean * mean + spread * spread);
        float a = static_cast<float>(3.0 * u(rng) * u(rng)), b = static_cast<float>(3.0 * u(rng));
        if (u(rng) < 0.1) a = b = 0.0f;
        if (!InfersTraversability(method) && a + b > 0.0f) b = 1.0f - (a = std::min(a, 1.0f));
        const CellEstimate e = EstimateCell(p, w, s, q, a, b);
        const uint8_t r = BlockReasons(p, w, s, q, a, b);
        const bool known = !std::isnan(e.elevation_weight);
        EXPECT_EQ(r != 0, known && e.state != CellState::kTraversable)
            << MethodName(method) << " w=" << w << " a=" << a << " b=" << b;
        // Seen too little (dynamics): unknown exactly when only a want of evidence fails and the
        // cell holds less than thin_evidence_weight full-kernel observations, or failing the
        // variance alone, less than thin_ground_weight.
        const bool thin = r == kNoValue || r == kHighVariance;
        const double limit = r == kHighVariance
                                 ? std::max(p.thin_evidence_weight, p.thin_ground_weight)
                                 : p.thin_evidence_weight;
        const bool little = w < limit * FullKernelWeight(p);
        EXPECT_EQ(known && e.state == CellState::kUnknown,
                  thin && little && dynamics == Dynamics::kOn)
            << MethodName(method) << " w=" << w << " a=" << a << " b=" << b;
        blocked += e.state == CellState::kNonTraversable;
        traversable += e.state == CellState::kTraversable;
      }
      EXPECT_GT(blocked, 100) << MethodName(method);  // both outcomes exercised
      EXPECT_GT(traversable, 100) << MethodName(method);
    }
  }
}

// A map whose cells are filled by hand, one statistic set per cell.
class HandMap {
 public:
  explicit HandMap(const MapParams& p = MapParams{})
      : map_(std::move(TerrainMap::Create(p)).value()) {}
  void Set(CellIndex c, double w, double s, double q, float a, float b) {
    Tile& t = map_->GetOrCreateTile(map_->geometry().TileOf(c));
    const int i = map_->geometry().LocalIndex(c);
    t.w()[i] = w;
    t.s()[i] = s;
    t.q()[i] = q;
    t.a()[i] = a;
    t.b()[i] = b;
  }
  // Flat ground at height z, observed well and traversable.
  void Ground(CellIndex c, double z) { Set(c, 10.0, 10.0 * z, 10.0 * z * z, 0.5f, 9.5f); }
  const TerrainMap& map() const { return *map_; }

 private:
  std::unique_ptr<TerrainMap> map_;
};

TEST(ScoreDriveTest, SharesAndReasonsOfTheDrivenCells) {
  // The paper's state (dynamics off), under which the thin cells below are blocked, so that
  // every reason is counted (with dynamics they are unknown: CellEstimateTest.SeenTooLittle...).
  MapParams paper;
  paper.dynamics = Dynamics::kOff;
  HandMap m(paper);
  std::vector<DrivenCell> driven;
  for (int x = 0; x < 10; ++x) driven.push_back({{x, 0}, 0.0});
  for (int x = 0; x < 10; ++x) m.Ground({x, 1}, 0.0);  // a row beside the path: a 2-D patch
  for (int x = 0; x < 5; ++x) m.Ground({x, 0}, 0.02);  // 5 traversable, 2 cm above the ground
  m.Set({5, 0}, 1.0, 0.0, 0.0, 0.0f, 0.0f);            // no value
  m.Set({6, 0}, 10.0, 0.0, 0.0, 8.0f, 2.0f);           // high mean
  m.Set({7, 0}, 1.0, 0.0, 0.0, 0.05f, 0.3f);           // high variance
  // (8, 0) and (9, 0) unknown.
  DriveScore s = ScoreDrive(m.map(), driven);
  EXPECT_EQ(s.driven, 10);
  EXPECT_EQ(s.known, 8);
  EXPECT_EQ(s.traversable, 5);
  EXPECT_EQ(s.blocked, 3);
  EXPECT_DOUBLE_EQ(s.known_share(), 0.8);
  EXPECT_DOUBLE_EQ(s.traversable_share(), 5.0 / 8.0);
  EXPECT_EQ(s.no_value, 1);
  EXPECT_EQ(s.high_mean, 1);
  EXPECT_EQ(s.high_variance, 1);
  EXPECT_EQ(s.disagreement, 0);
  EXPECT_EQ(s.only_mean, 1);
  EXPECT_EQ(s.only_variance, 1);
  // The high-mean cell's neighbourhood: its own height 0 beside ground at 0.02 m: no criterion
  // exceeded now (the evidence is history).
  EXPECT_EQ(s.mean_flat_now, 1);
  EXPECT_EQ(s.ground_cells, 8);
  EXPECT_NEAR(s.ground_bias, (5 * 0.02) / 8.0, 1e-6);  // elevations are floats

  // Mutations move the numbers: the unknown cell observed as ground, the variance cell given
  // evidence, a step beside the high-mean cell.
  m.Ground({8, 0}, 0.0);
  m.Set({7, 0}, 10.0, 0.0, 0.0, 0.5f, 9.5f);
  m.Ground({6, 1}, 0.5);
  s = ScoreDrive(m.map(), driven);
  EXPECT_EQ(s.known, 9);
  EXPECT_EQ(s.traversable, 7);
  EXPECT_EQ(s.high_variance, 0);
  EXPECT_EQ(s.mean_step, 1);
  EXPECT_EQ(s.mean_flat_now, 0);
}

TEST(CompareMapsTest, CommonCellsTheirStatesAndElevationDifferences) {
  HandMap a, b;
  for (int x = 0; x < 4; ++x) a.Ground({x, 0}, 0.0);
  b.Ground({0, 0}, 0.1);
  b.Ground({1, 0}, -0.1);
  b.Set({2, 0}, 10.0, 0.0, 0.0, 8.0f, 2.0f);  // blocked in b only, by the mean
  b.Ground({5, 0}, 0.0);                      // known in b only
  const MapAgreement m = CompareMaps(a.map(), b.map());
  EXPECT_EQ(m.common, 3);
  EXPECT_EQ(m.only_a, 1);
  EXPECT_EQ(m.only_b, 1);
  EXPECT_EQ(m.state_agree, 2);
  EXPECT_DOUBLE_EQ(m.agreement(), 2.0 / 3.0);
  EXPECT_EQ(m.b_blocked_only, 1);
  EXPECT_EQ(m.split_high_mean, 1);
  EXPECT_NEAR(m.dz_mean, 0.0, 1e-6);                   // elevations are floats
  EXPECT_NEAR(m.dz_rms, std::sqrt(0.02 / 3.0), 1e-6);  // elevations are floats
  EXPECT_NEAR(m.dz_abs_max, 0.1, 1e-6);                // elevations are floats
  // Restricted to two cells.
  const std::vector<CellIndex> cells = {{0, 0}, {3, 0}};
  const MapAgreement r = CompareMaps(a.map(), b.map(), cells);
  EXPECT_EQ(r.common, 1);
  EXPECT_EQ(r.only_a, 1);
  EXPECT_EQ(r.state_agree, 1);
}

}  // namespace
}  // namespace bgkmap::eval
