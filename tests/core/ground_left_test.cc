// Ground left by a forgotten object (docs/semantics.md, "Dynamics"): the free-space evidence
// resets the Beta counts within l of every contradicted cell; where a cell was forgotten, the
// cells within l of it, and those within robot_radius + l (as far as its surface's evidence
// reached) whose counts say "obstacle", re-learn v from the surface left there, at the
// weight of the cell's elevations (between one observation's and one full-kernel
// observation's), when that surface crosses no critical value. Without it, ground a vehicle
// stood beside stays blocked ("no value") until a scan's returns land within l of it. And the
// remains of an object mixed into the ground around it go when a ray passes below their top.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

const Eigen::Vector3d kSensor(0.05, 0.05, 1.0);

std::vector<Point3f> SensorFrame(const std::vector<Point3f>& map_frame) {
  return InSensorFrame(map_frame, kSensor);
}

// Flat ground 3-8 m ahead with a 0.5 x 1 m box, 0.8 m tall, at 5.5-6 m (and its shadow).
std::vector<Point3f> GroundWithBox() { return GroundAhead(LaneBox{5.5f, 6.0f, 0.8f}); }

// The box has gone: returns only from the ground 7-8 m ahead, whose rays pass low over where it
// stood; none within l of the ground in front of it.
std::vector<Point3f> FarGroundOnly() { return GroundStripAhead(7.05f, 10); }

// The scene moved `ahead` metres along x (the sensor with it).
std::unique_ptr<TerrainMap> BoxThenGone(MapParams p,
                                        const std::vector<Point3f>& last = FarGroundOnly(),
                                        float ahead = 0.0f) {
  const Eigen::Vector3d sensor = kSensor + Eigen::Vector3d(ahead, 0.0, 0.0);
  const auto moved = [&](std::vector<Point3f> pts) {
    for (Point3f& q : pts) q.x += ahead;
    return InSensorFrame(pts, sensor);
  };
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  for (int k = 0; k < 3; ++k)
    EXPECT_TRUE(map->IntegrateScan(moved(GroundWithBox()), At(sensor)).ok());
  EXPECT_TRUE(map->IntegrateScan(moved(last), At(sensor)).ok());
  return map;
}

TEST(GroundLeftTest, GroundInFrontOfAForgottenObjectIsTraversableWithoutNewReturns) {
  const std::unique_ptr<TerrainMap> map = BoxThenGone(MapParams{});
  // The box is forgotten (no ray reaches the ground under it: unknown).
  EXPECT_EQ(map->EstimateAt(5.75, 0.05).state, CellState::kUnknown);
  // The ground in front of it learnt "obstacle near" while the box stood; its counts were reset
  // and no return of the last scan is within l of it. It re-learns from the flat ground left.
  for (double y = -0.25; y <= 0.26; y += 0.1) {
    for (double x : {5.25, 5.35}) {
      const CellEstimate e = map->EstimateAt(x, y);
      EXPECT_EQ(e.state, CellState::kTraversable) << x << ", " << y;
      EXPECT_LT(e.traversability, 0.5f) << x << ", " << y;
    }
  }
}

TEST(GroundLeftTest, GroundAsFarAsTheObjectsEvidenceReachedReLearns) {
  // The box's step made v = 1 at the ground within robot_radius of it, and that spread within l
  // further: obstacle evidence reached robot_radius + l (0.6 m) in front of the box, beyond the
  // l within which the contradicted cells reset counts. Where it made a cell there say
  // "obstacle", that cell re-learns too, or it keeps saying so of an obstacle that is gone (a
  // car's trail, 0.3-0.6 m behind it); where the cell's own ground evidence won, it is kept.
  const MapParams p;
  std::unique_ptr<TerrainMap> with_box = TerrainMap::Create(p).value();
  for (int k = 0; k < 3; ++k)
    EXPECT_TRUE(with_box->IntegrateScan(SensorFrame(GroundWithBox()), At(kSensor)).ok());
  const std::unique_ptr<TerrainMap> map = BoxThenGone(p);
  for (double y = -0.25; y <= 0.26; y += 0.1) {
    // 0.4 m from the box's cells: blocked by it, re-learnt.
    const CellEstimate blocked = with_box->EstimateAt(5.15, y), now = map->EstimateAt(5.15, y);
    EXPECT_GE(blocked.traversability, p.trav_threshold) << y;
    EXPECT_EQ(now.state, CellState::kTraversable) << y;
    EXPECT_LT(now.traversability, 0.1f) << y;
    // 0.5 m: obstacle evidence there too, but its own ground evidence won; kept as it was.
    const CellEstimate ground = with_box->EstimateAt(5.05, y), kept = map->EstimateAt(5.05, y);
    EXPECT_GT(ground.traversability, 0.2f) << y;
    EXPECT_EQ(ground.state, CellState::kTraversable) << y;
    EXPECT_EQ(kept.traversability, ground.traversability) << y;
    EXPECT_EQ(kept.traversability_variance, ground.traversability_variance) << y;
  }
}

// The same scenes on ground rising 1 in `rise` along x (the box stands on it).
std::vector<Point3f> Sloped(std::vector<Point3f> pts, float rise) {
  for (Point3f& q : pts) q.z += (q.x - 3.0f) / rise;
  return pts;
}

TEST(GroundLeftTest, ReLearntGroundIsAsSureAsTheElevationsItRestsOn) {
  // On a slope the ground left re-learns v > 0. The cells in front of the box were seen by every
  // scan (their elevation weight is at least one full-kernel observation's): the v they re-learn
  // from that surface weighs as much, not one observation's (whose variance, v (1 - v) / 2, blocks
  // any v between 0.07 and 0.93 on the variance threshold of 0.05).
  const MapParams p;
  const Eigen::Vector3d sensor = kSensor;
  for (float rise : {20.0f, 12.0f}) {
    std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(
          map->IntegrateScan(InSensorFrame(Sloped(GroundWithBox(), rise), sensor), At(sensor))
              .ok());
    }
    EXPECT_TRUE(
        map->IntegrateScan(InSensorFrame(Sloped(FarGroundOnly(), rise), sensor), At(sensor)).ok());
    EXPECT_EQ(map->EstimateAt(5.75, 0.05).state, CellState::kUnknown) << "the box is forgotten";
    for (double y = -0.25; y <= 0.26; y += 0.1) {
      const CellEstimate e = map->EstimateAt(5.15, y);
      EXPECT_GT(e.traversability, 0.1f) << rise << ", " << y;  // a slope, not flat ground
      EXPECT_EQ(e.state, CellState::kTraversable) << rise << ", " << y;
      EXPECT_LT(e.traversability_variance, 0.05f) << rise << ", " << y;
    }
  }
}

TEST(GroundLeftTest, RemainsMixedIntoGroundGoWhenARayPassesThroughThem) {
  // A 1 m box stands for one scan on ground seen five times. The kernel blends a little of it
  // into the ground cells around it (a share p of their weight): their mean rises by p, their
  // deviation by sqrt(p (1 - p)) m, above step_crit, while their Beta counts, re-learnt once the
  // box is forgotten, say ground. The next scans' rays pass through them a few cm above the
  // ground, below the top they have seen (mean plus deviation) but not by clear_margin: so they
  // stayed blocked by their disagreement (14-22 cells for four scans). A ray below the top of
  // such a cell has gone through the remains (they stand above the mean by more than their
  // deviation), which are then cut like any contradicted surface.
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(MapParams{}).value();
  for (int k = 0; k < 5; ++k)
    EXPECT_TRUE(map->IntegrateScan(SensorFrame(GroundAhead()), At(kSensor)).ok());
  EXPECT_TRUE(
      map->IntegrateScan(SensorFrame(GroundAhead(LaneBox{5.5f, 6.0f, 1.0f})), At(kSensor)).ok());
  for (int k = 0; k < 2; ++k)
    EXPECT_TRUE(map->IntegrateScan(SensorFrame(GroundAhead()), At(kSensor)).ok());
  for (double x = 4.85; x < 6.7; x += 0.1) {
    for (double y = -0.65; y < 0.7; y += 0.1) {
      const CellEstimate e = map->EstimateAt(x, y);
      EXPECT_EQ(e.state, CellState::kTraversable) << x << ", " << y;
      EXPECT_EQ(e.block_reasons, 0) << x << ", " << y;
    }
  }
}

TEST(GroundLeftTest, ReLearningAddsNoObstacleEvidence) {
  // A wall as tall as the box stands beside it and stays; the last scan's rays pass under the
  // box only. The wall's cells are within l of the forgotten box: their counts are reset, and the
  // surface left around them has the wall's step, v = 1, which is not re-learnt: they keep no
  // Beta counts (blocked for want of a value) until a return comes.
  std::vector<Point3f> scan = GroundWithBox();
  for (Point3f& q : scan) {
    if (q.x > 5.5f && q.x < 6.0f && q.y > 0.5f && q.y < 0.7f) q.z = 0.8f;
  }
  std::erase_if(scan, [](const Point3f& q) { return q.x > 6.0f && q.y > 0.5f && q.y < 0.7f; });
  std::vector<Point3f> far_ground;
  for (const Point3f& q : FarGroundOnly()) {
    if (q.y > -0.5f && q.y < 0.5f) far_ground.push_back(q);
  }
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(MapParams{}).value();
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(map->IntegrateScan(SensorFrame(scan), At(kSensor)).ok());
  }
  EXPECT_TRUE(map->IntegrateScan(SensorFrame(far_ground), At(kSensor)).ok());
  for (double x = 5.65; x < 6.0; x += 0.1) {
    const CellEstimate e = map->EstimateAt(x, 0.55);
    EXPECT_EQ(e.state, CellState::kNonTraversable) << x;
    EXPECT_EQ(e.block_reasons, kBlockedNoValue) << x;
  }
}

// The far ground only where the box stood: the rays pass under the box, not beside it.
std::vector<Point3f> FarGroundBehindTheBox() {
  std::vector<Point3f> pts = FarGroundOnly();
  std::erase_if(pts, [](const Point3f& q) { return q.y < -0.5f || q.y > 0.5f; });
  return pts;
}

TEST(GroundLeftTest, TheSameMapWhateverTheTiling) {
  // The cells beside the box re-learn from a patch reaching l + robot_radius beyond the rays'
  // cells; a tile border there (9 cells: at y = 0.9 m) must not change what they read. Tiles of
  // 100 and 256 cells hold rows of several 64-bit words in the marks of the reach of what was
  // forgotten (core/src/tile_row_marks.h): with the scene 1.5 m further, the box stands on cells
  // 70-75 and the ground it leaves in front of it, cells 64-69, lies past the words' border at
  // 64 (mutation: every row range marked in its first word).
  for (const float ahead : {0.0f, 1.5f}) {
    for (const std::vector<Point3f>& last : {FarGroundOnly(), FarGroundBehindTheBox()}) {
      MapParams p;
      p.tile_size = 64;
      const std::unique_ptr<TerrainMap> reference = BoxThenGone(p, last, ahead);
      const CellBox box = reference->KnownBounds();
      for (int tile_size : {8, 9, 20, 100, 256}) {
        p.tile_size = tile_size;
        const std::unique_ptr<TerrainMap> map = BoxThenGone(p, last, ahead);
        int differing = 0;
        for (int y = box.min.y - 8; y <= box.max.y + 8; ++y) {
          for (int x = box.min.x - 8; x <= box.max.x + 8; ++x) {
            const CellEstimate a = reference->Estimate({x, y}), b = map->Estimate({x, y});
            const bool same =
                a.state == b.state &&
                (a.state == CellState::kUnknown ||
                 (a.elevation == b.elevation && a.traversability == b.traversability &&
                  a.traversability_variance == b.traversability_variance));
            differing += !same;
          }
        }
        EXPECT_EQ(differing, 0) << "tile size " << tile_size << ", " << last.size() << " points, "
                                << ahead << " m ahead";
      }
    }
  }
}

}  // namespace
}  // namespace bgkmap::testing
