// Why driven cells are blocked, from their history (eval/drive_causes.h): hand-made cells whose
// statistics change from scan to scan as the rules would change them (a free-space cut, a Beta
// reset, evidence learnt while a vehicle stood there), each judged to its own cause, on the final
// map and on arrival. Mutation checked by hand: a Beta reset never detected fails
// EachHistoryToItsCause.
#include "bgkmap/eval/drive_causes.h"

#include <gtest/gtest.h>

#include <cmath>

namespace bgkmap::eval {
namespace {

class HandMap {
 public:
  HandMap() : map_(std::move(TerrainMap::Create(MapParams{})).value()) {}
  void Set(CellIndex c, double w, double z, float a, float b, double spread = 0.0) {
    Tile& t = map_->GetOrCreateTile(map_->geometry().TileOf(c));
    const int i = map_->geometry().LocalIndex(c);
    t.w()[i] = w;
    t.s()[i] = w * z;
    t.q()[i] = w * (z * z + spread * spread);
    t.a()[i] = a;
    t.b()[i] = b;
  }
  void Ground(CellIndex c, double z = 0.0) { Set(c, 10.0, z, 0.5f, 9.5f); }
  const TerrainMap& map() const { return *map_; }

 private:
  std::unique_ptr<TerrainMap> map_;
};

// Driven cells along y = 0, every third column, each in a ground patch of its own.
CellIndex Cell(int i) { return {3 * i * 3, 0}; }

TEST(DriveCausesTest, EachHistoryToItsCause) {
  HandMap m;
  std::vector<DrivenCell> driven;
  for (int i = 0; i < 10; ++i) {
    driven.push_back({Cell(i), 0.0, 0});
    for (int dx = -2; dx <= 2; ++dx) {  // the patch around each: ground, for its surface
      for (int dy = -2; dy <= 2; ++dy) m.Ground({Cell(i).x + dx, dy});
    }
  }
  driven[3].first_scan = 2;  // arrived at by scan 2: judged on the map after scan 1
  // Vehicle near cell 5 at scan 0 only.
  auto near = [](int k, CellIndex c) { return k == 0 && c == Cell(5); };
  DriveCauses causes(driven, near, /*recent_scans=*/5);
  const Pose pose;  // at the origin

  // Scan 0.
  m.Set(Cell(1), 0.0, 0.0, 0.0f, 0.0f);        // never seen
  m.Set(Cell(2), 5.0, 0.0, 0.5f, 4.5f);        // seen, then forgotten at scan 1
  m.Set(Cell(4), 1.0, 0.0, 0.05f, 0.3f);       // never more than a little evidence
  m.Set(Cell(5), 10.0, 0.0, 8.0f, 2.0f);       // obstacle evidence while a vehicle was near
  m.Set(Cell(6), 10.0, 0.0, 8.0f, 2.0f);       // obstacle evidence, no vehicle, flat now
  m.Set(Cell(8), 10.0, 0.0, 0.5f, 9.5f, 0.5);  // observations 0.5 m apart
  m.Set(Cell(9), 1.0, 0.0, 0.0f, 0.0f);        // elevation, no traversability evidence
  causes.AfterScan(0, pose, m.map());
  // Scan 1: cell 2 cut to nothing, cell 3 reset to little evidence, a step beside cell 7 whose
  // evidence is high.
  m.Set(Cell(2), 0.0, 0.0, 0.0f, 0.0f);
  m.Set(Cell(3), 10.0, 0.0, 0.05f, 0.3f);
  m.Set(Cell(7), 10.0, 0.0, 8.0f, 2.0f);
  m.Ground({Cell(7).x + 1, 1}, 0.5);
  causes.AfterScan(1, pose, m.map());
  causes.Finish(m.map());

  EXPECT_EQ(causes.final_cause(0), Cause::kTraversable);
  EXPECT_EQ(causes.final_cause(1), Cause::kUnknownNeverSeen);
  EXPECT_EQ(causes.final_cause(2), Cause::kUnknownForgotten);
  EXPECT_EQ(causes.final_cause(3), Cause::kVarianceAfterReset);
  EXPECT_EQ(causes.final_cause(4), Cause::kVarianceSparse);
  EXPECT_EQ(causes.final_cause(5), Cause::kMeanVehicle);
  EXPECT_EQ(causes.final_cause(6), Cause::kMeanHistory);
  EXPECT_EQ(causes.final_cause(7), Cause::kMeanSurfaceNow);
  EXPECT_EQ(causes.final_cause(8), Cause::kDisagreement);
  EXPECT_EQ(causes.final_cause(9), Cause::kNoValue);
  const CauseCounts& f = causes.final();
  EXPECT_EQ(f.judged, 10);
  EXPECT_EQ(f.cells_cut, 1);    // cell 2
  EXPECT_EQ(f.cells_reset, 2);  // cells 2 and 3
  for (int c = 0; c < kCauseCount; ++c) EXPECT_EQ(f.n[c], 1) << CauseName(Cause(c));
  // The high-mean cells' ranges from the sensor (at the origin) when their evidence came.
  auto range = [](int i) { return std::hypot((Cell(i).x + 0.5) * 0.1, 0.05); };
  EXPECT_NEAR(f.mean_evidence_range(), (range(5) + range(6) + range(7)) / 3, 1e-9);
  // On arrival: scan 0 arrives at everything but cell 3 (nothing judged: no map before scan 0);
  // cell 3 arrived at by scan 2, judged after scan 1.
  EXPECT_EQ(causes.on_arrival().judged, 1);
  EXPECT_EQ(causes.on_arrival()[Cause::kVarianceAfterReset], 1);
}

TEST(DriveCausesTest, AResetLongAgoIsLittleEvidenceNow) {
  HandMap m;
  const std::vector<DrivenCell> driven = {{{0, 0}, 0.0, 0}};
  for (int dx = -2; dx <= 2; ++dx)
    for (int dy = -2; dy <= 2; ++dy) m.Ground({dx, dy});
  DriveCauses causes(driven, {}, /*recent_scans=*/2);
  causes.AfterScan(0, Pose{}, m.map());
  m.Set({0, 0}, 10.0, 0.0, 0.05f, 0.3f);  // reset at scan 1
  causes.AfterScan(1, Pose{}, m.map());
  causes.AfterScan(2, Pose{}, m.map());
  causes.AfterScan(3, Pose{}, m.map());
  causes.Finish(m.map());
  EXPECT_EQ(causes.final_cause(0), Cause::kVarianceSparse);
}

}  // namespace
}  // namespace bgkmap::eval
