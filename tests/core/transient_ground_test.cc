// Transient objects (docs/semantics.md, "Transient objects"): with transient_confirm_s > 0 the
// ground under something that appeared where the map saw traversable ground is kept aside; if
// the appearance is not seen for transient_expire_s before it was seen transient_confirm_s after
// it appeared, the ground comes back; if it was, the obstacle stays. The case it is for: a car
// following the robot covers the road the robot drove, and the car itself hides the road it
// leaves behind from every later scan.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

const Eigen::Vector3d kSensor(0.05, 0.05, 1.0);
constexpr int64_t kScanNs = 100'000'000;  // 10 Hz

// Flat ground 3-8 m ahead; with `box`, a 0.5 x 1 m box, 1 m tall, at 5.5-6 m and no return from
// its shadow.
std::vector<Point3f> Ground(bool box) {
  return box ? GroundAhead(LaneBox{5.5f, 6.0f, 1.0f}) : GroundAhead();
}

// The box has moved 1.5 m toward the sensor (a car following the robot): its returns at 4-4.5 m,
// 1.2 m tall, hide the place where it stood; the ground 3-4 m and beside it is seen.
std::vector<Point3f> BoxMovedCloser() { return GroundAhead(LaneBox{4.0f, 4.5f, 1.2f}); }

// Only the ground 3-5 m ahead: nothing within l of where the box stood, but nothing hides it
// either (a place in view that no return happens to sample).
std::vector<Point3f> NearGroundOnly() { return GroundStripAhead(3.05f, 20); }

MapParams Transients(double confirm_s) {
  MapParams p;
  p.transient_confirm_s = confirm_s;
  p.transient_expire_s = 1.0;
  return p;
}

// 5 scans of bare ground, `box_scans` with the box, then `after_scans` of `after` (by default
// the box moved closer, hiding where it stood); stamped at 10 Hz unless `stamped` is false.
std::unique_ptr<TerrainMap> Drive(const MapParams& p, int box_scans, int after_scans,
                                  bool stamped = true,
                                  const std::vector<Point3f>& after = BoxMovedCloser()) {
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  int64_t t = 0;
  auto scan = [&](const std::vector<Point3f>& pts) {
    t += kScanNs;
    EXPECT_TRUE(
        map->IntegrateScan(InSensorFrame(pts, kSensor), At(kSensor), false, stamped ? t : 0).ok());
  };
  for (int k = 0; k < 5; ++k) scan(Ground(false));
  for (int k = 0; k < box_scans; ++k) scan(Ground(true));
  for (int k = 0; k < after_scans; ++k) scan(after);
  return map;
}

// The later scans write the tiles of x in [0, 6.4) m: every entry there is resolved (decided in
// the tiles a scan writes; those beyond 6.4 m keep theirs until a scan writes them).
void ExpectResolvedWhereWritten(const TerrainMap& map) {
  map.ForEachTile([](TileKey key, const Tile& tile) {
    if (key.x == 0) {
      EXPECT_TRUE(tile.pending().empty()) << key.x << "," << key.y;
    }
  });
}

int BoxCellsIn(const TerrainMap& map, CellState state) {
  int n = 0;
  for (double x = 5.55; x < 6.0; x += 0.1) {
    for (double y = -0.45; y < 0.5; y += 0.1) n += map.EstimateAt(x, y).state == state;
  }
  return n;
}

TEST(TransientGroundTest, AnAppearanceSeenBrieflyAndThenHiddenGivesTheGroundBack) {
  // Shown while seen: the box is an obstacle at once.
  const std::unique_ptr<TerrainMap> shown = Drive(Transients(2.0), 2, 0);
  EXPECT_EQ(BoxCellsIn(*shown, CellState::kNonTraversable), 50);
  // 0.2 s seen, then hidden for 1.5 s (more than transient_expire_s): ground again.
  const std::unique_ptr<TerrainMap> later = Drive(Transients(2.0), 2, 15);
  EXPECT_EQ(BoxCellsIn(*later, CellState::kTraversable), 50);
  EXPECT_NEAR(later->EstimateAt(5.75, 0.05).elevation, 0.0, 0.01);
  // Hidden for less than transient_expire_s: still the obstacle.
  const std::unique_ptr<TerrainMap> soon = Drive(Transients(2.0), 2, 5);
  EXPECT_EQ(BoxCellsIn(*soon, CellState::kNonTraversable), 50);
}

TEST(TransientGroundTest, AnAppearanceInViewButNotSampledStays) {
  // Seen for 0.2 s, then 1.5 s in which no return lands near it though nothing hides it (a sparse
  // sensor's rings): not taken back, it may still be there.
  const std::unique_ptr<TerrainMap> map = Drive(Transients(2.0), 2, 15, true, NearGroundOnly());
  EXPECT_EQ(BoxCellsIn(*map, CellState::kNonTraversable), 50);
  ExpectResolvedWhereWritten(*map);
}

TEST(TransientGroundTest, WithoutTheRuleTheHiddenPlaceKeepsTheObstacle) {
  const std::unique_ptr<TerrainMap> map = Drive(Transients(0.0), 2, 15);
  EXPECT_EQ(BoxCellsIn(*map, CellState::kNonTraversable), 50);
}

TEST(TransientGroundTest, AnAppearanceSeenLongerThanTheConfirmationStays) {
  // Seen for 2.5 s (> 2 s), then hidden for 3 s: confirmed, an obstacle as without the rule. The
  // box's entries (kept at 0.6 s) are all resolved; the moved box, which stays, keeps spawning
  // entries at the edge of its reach, and those are not what this test is about.
  const std::unique_ptr<TerrainMap> map = Drive(Transients(2.0), 25, 30);
  EXPECT_EQ(BoxCellsIn(*map, CellState::kNonTraversable), 50);
  map->ForEachTile([](TileKey key, const Tile& tile) {
    for (const Tile::PendingGround& g : tile.pending()) {
      EXPECT_GT(g.appeared_ns, 3 * kScanNs * 10) << key.x << "," << key.y << " cell " << g.local;
    }
  });
}

TEST(TransientGroundTest, UnstampedScansKeepNothingAside) {
  const std::unique_ptr<TerrainMap> with = Drive(Transients(2.0), 2, 15, false);
  const std::unique_ptr<TerrainMap> without = Drive(Transients(0.0), 2, 15, false);
  with->ForEachTile([&](TileKey key, const Tile& tile) {
    EXPECT_TRUE(tile.pending().empty());
    EXPECT_TRUE(tile == *without->FindTile(key)) << key.x << "," << key.y;
  });
}

TEST(TransientGroundTest, AKeptGroundIsPartOfTheTile) {
  // Pending ground travels with a tile: copies carry it and equality sees it.
  const std::unique_ptr<TerrainMap> map = Drive(Transients(2.0), 2, 1);
  const Tile* tile = map->FindTile({0, 0});
  ASSERT_NE(tile, nullptr);
  ASSERT_FALSE(tile->pending().empty());
  Tile copy(*tile);
  EXPECT_TRUE(copy == *tile);
  copy.pending().pop_back();
  EXPECT_FALSE(copy == *tile);
  // Merged into an empty tile it is kept; into a tile with statistics, dropped.
  Tile empty(tile->tile_size());
  empty.Add(*tile);
  EXPECT_EQ(empty.pending(), tile->pending());
  empty.Add(*tile);
  EXPECT_TRUE(empty.pending().empty());
  // A packed tile merges the same way (it is unpacked on the way).
  std::unique_ptr<Tile> packed = Tile::PackedCopy(*tile);
  Tile into(tile->tile_size());
  into.Add(*packed);
  EXPECT_EQ(into.pending(), tile->pending());
}

}  // namespace
}  // namespace bgkmap::testing
