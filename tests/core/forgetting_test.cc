// Forgetting (docs/semantics.md, "Forgetting"): with half_life_s > 0 a scan stamped t weighs
// 2^(-(T - t) / half_life) at a tile as of map time T, applied lazily per tile; merges bring both
// tiles to the later stamp, then add; half_life_s = 0 changes nothing, bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "synthetic_terrain.h"

namespace bgkmap::testing {
namespace {

constexpr int64_t kSecond = 1'000'000'000;

// A map-frame cloud (no sensor, so no free-space evidence): a 3 x 3 m patch of a tilted plane
// at `height`, around (cx, cy), across tile borders (tiles are 6.4 m; the patch straddles 0).
std::vector<Point3f> Patch(double cx, double cy, double height, unsigned seed) {
  std::vector<Point3f> pts;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int k = 0; k < 3000; ++k) {
    const double x = cx + u(rng), y = cy + u(rng);
    pts.push_back({static_cast<float>(x), static_cast<float>(y),
                   static_cast<float>(height + 0.05 * x - 0.03 * y)});
  }
  return pts;
}

struct StampedScan {
  std::vector<Point3f> points;
  int64_t stamp;
};

// Four scans over overlapping patches, stamped 1 s, 3 s, 3.5 s and 10 s.
std::vector<StampedScan> Scans() {
  return {{Patch(0.0, 0.0, 0.0, 1), 1 * kSecond},
          {Patch(0.8, -0.5, 0.4, 2), 3 * kSecond},
          {Patch(-0.6, 0.3, 1.0, 3), 3 * kSecond + kSecond / 2},
          {Patch(20.0, 20.0, 0.2, 4), 10 * kSecond}};  // far away: other tiles age untouched
}

MapParams ForgettingParams(double half_life_s) {
  MapParams p;  // dynamics on, bgk+
  p.half_life_s = half_life_s;
  p.max_confidence_scans = 1e9;  // caps off: the statistics stay linear in the evidence
  return p;
}

std::unique_ptr<TerrainMap> Build(const MapParams& p, const std::vector<StampedScan>& scans,
                                  const std::vector<int>& order) {
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  for (int i : order) {
    EXPECT_TRUE(
        map->IntegrateScan(scans[i].points, Pose{}, /*frame_is_map=*/true, scans[i].stamp).ok());
  }
  return map;
}

bool SameTiles(const TerrainMap& a, const TerrainMap& b) {
  if (a.tile_count() != b.tile_count()) return false;
  bool same = true;
  a.ForEachTile([&](TileKey key, const Tile& t) {
    const Tile* o = b.FindTile(key);
    same = same && o != nullptr && *o == t;
  });
  return same;
}

// Every cell's W, S, Q as of map time T (each tile read with its decay from its stamp to T).
struct Stats {
  double w = 0, s = 0, q = 0;
};
std::map<std::pair<int, int>, Stats> AsOf(const TerrainMap& map, int64_t T, double half_life_s) {
  std::map<std::pair<int, int>, Stats> out;
  const int n = map.params().tile_size;
  map.ForEachTile([&](TileKey key, const Tile& t) {
    const double f = half_life_s > 0
                         ? std::exp2(-static_cast<double>(T - t.stamp_ns()) / 1e9 / half_life_s)
                         : 1.0;
    for (int i = 0; i < t.cell_count(); ++i) {
      if (t.w()[i] == 0.0) continue;
      out[{key.x * n + i % n, key.y * n + i / n}] = {f * t.w()[i], f * t.s()[i], f * t.q()[i]};
    }
  });
  return out;
}

void ExpectClose(const std::map<std::pair<int, int>, Stats>& got,
                 const std::map<std::pair<int, int>, Stats>& want, double rel) {
  ASSERT_EQ(got.size(), want.size());
  for (const auto& [cell, g] : got) {
    const auto it = want.find(cell);
    ASSERT_NE(it, want.end());
    const Stats& e = it->second;
    EXPECT_NEAR(g.w, e.w, rel * e.w) << cell.first << "," << cell.second;
    EXPECT_NEAR(g.s, e.s, rel * (std::abs(e.s) + e.w)) << cell.first << "," << cell.second;
    EXPECT_NEAR(g.q, e.q, rel * (std::abs(e.q) + e.w)) << cell.first << "," << cell.second;
  }
}

// The brute force: each scan integrated alone without forgetting, weighted 2^(-(T - t) / h) and
// summed; nothing of the lazy per-tile ageing is used.
std::map<std::pair<int, int>, Stats> BruteForce(const std::vector<StampedScan>& scans, int64_t T,
                                                double h) {
  std::map<std::pair<int, int>, Stats> out;
  for (const StampedScan& scan : scans) {
    const std::unique_ptr<TerrainMap> alone = Build(ForgettingParams(0), {scan}, {0});
    const double f = std::exp2(-static_cast<double>(T - scan.stamp) / 1e9 / h);
    for (const auto& [cell, st] : AsOf(*alone, T, 0)) {
      Stats& o = out[cell];
      o.w += f * st.w;
      o.s += f * st.s;
      o.q += f * st.q;
    }
  }
  return out;
}

// Mutations checked: Advance not scaling (Tile::Scale a no-op), Gain returning 1 for late scans,
// DecayFactor with exp2(-dt/h) replaced by exp(-dt/h): each fails this test.
TEST(ForgettingTest, EachScanWeighsTwoToTheMinusItsAgeInHalfLives) {
  const std::vector<StampedScan> scans = Scans();
  const int64_t T = 10 * kSecond;
  const double h = 2.0;
  const std::unique_ptr<TerrainMap> map = Build(ForgettingParams(h), scans, {0, 1, 2, 3});
  ExpectClose(AsOf(*map, T, h), BruteForce(scans, T, h), 1e-12);
  // Tiles the last scan did not reach stay at the time of the last scan that changed them.
  const Tile* origin = map->FindTile({0, 0});
  ASSERT_NE(origin, nullptr);
  EXPECT_EQ(origin->stamp_ns(), 3 * kSecond + kSecond / 2);
  EXPECT_EQ(map->FindTile({3, 3})->stamp_ns(), 10 * kSecond);
}

// Mutation checked: Gain returning 1 (a late scan counted as new) fails the first expectation.
TEST(ForgettingTest, LateScansFromAnotherRobotGiveTheSameMapInAnyOrder) {
  const std::vector<StampedScan> scans = Scans();
  const int64_t T = 10 * kSecond;
  const double h = 2.0;
  const std::map<std::pair<int, int>, Stats> want = BruteForce(scans, T, h);
  for (const std::vector<int>& order :
       std::vector<std::vector<int>>{{3, 2, 1, 0}, {1, 0, 3, 2}, {2, 0, 1, 3}}) {
    SCOPED_TRACE(::testing::Message() << order[0] << order[1] << order[2] << order[3]);
    const std::unique_ptr<TerrainMap> map = Build(ForgettingParams(h), scans, order);
    ExpectClose(AsOf(*map, T, h), want, 1e-12);
    // The same order twice: bitwise the same map, stamps included.
    EXPECT_TRUE(SameTiles(*map, *Build(ForgettingParams(h), scans, order)));
  }
}

// A statistic halves per half-life: read where a later scan elsewhere in the tile brought it on.
TEST(ForgettingTest, AHalfLifeHalvesACellsWeight) {
  MapParams p = ForgettingParams(5.0);
  p.method = Method::kOneStep;  // raw elevation: one observation adds 1 to W at its cell
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
  const std::vector<Point3f> a = {{0.05f, 0.05f, 0.3f}};
  const std::vector<Point3f> b = {{3.05f, 3.05f, 0.0f}};  // same tile, another cell
  ASSERT_TRUE(map->IntegrateScan(a, Pose{}, true, 100 * kSecond).ok());
  EXPECT_EQ(map->EstimateAt(0.05, 0.05).elevation_weight, 1.0f);
  ASSERT_TRUE(map->IntegrateScan(b, Pose{}, true, 105 * kSecond).ok());
  EXPECT_EQ(map->EstimateAt(0.05, 0.05).elevation_weight, 0.5f);
  ASSERT_TRUE(map->IntegrateScan(b, Pose{}, true, 115 * kSecond).ok());
  EXPECT_EQ(map->EstimateAt(0.05, 0.05).elevation_weight, 0.125f);
  EXPECT_FLOAT_EQ(map->EstimateAt(0.05, 0.05).elevation, 0.3f);  // the mean stays (lambda = 0)
  // A scan older than the tile counts for what it would have kept by now: 2^-3.
  ASSERT_TRUE(map->IntegrateScan(a, Pose{}, true, 100 * kSecond).ok());
  EXPECT_EQ(map->EstimateAt(0.05, 0.05).elevation_weight, 0.25f);
  // Unstamped (0): neither ages the tile nor is aged.
  ASSERT_TRUE(map->IntegrateScan(a, Pose{}, true, 0).ok());
  EXPECT_EQ(map->EstimateAt(0.05, 0.05).elevation_weight, 1.25f);
  EXPECT_EQ(map->FindTile({0, 0})->stamp_ns(), 115 * kSecond);
}

// Mutation checked: AddTile adding without bringing the older tile to the later stamp fails
// the closeness.
TEST(ForgettingTest, MergeBringsBothToTheLaterStampThenAdds) {
  const std::vector<StampedScan> scans = Scans();
  const double h = 2.0;
  const MapParams p = ForgettingParams(h);
  // Robot A: scans 0 and 3; robot B: scans 1 and 2 (A's last is later than B's).
  const std::unique_ptr<TerrainMap> a = Build(p, scans, {0, 3});
  const std::unique_ptr<TerrainMap> b = Build(p, scans, {1, 2});
  auto merge = [&](const TerrainMap& first, const TerrainMap& second) {
    std::unique_ptr<TerrainMap> m = TerrainMap::Create(p).value();
    first.ForEachTile([&](TileKey k, const Tile& t) { m->AddTile(k, t); });
    second.ForEachTile([&](TileKey k, const Tile& t) { m->AddTile(k, t); });
    return m;
  };
  const std::unique_ptr<TerrainMap> ab = merge(*a, *b);
  const std::unique_ptr<TerrainMap> ba = merge(*b, *a);
  EXPECT_TRUE(SameTiles(*ab, *ba));  // addition of the same aged tiles commutes, bitwise
  const int64_t T = 10 * kSecond;
  ExpectClose(AsOf(*ab, T, h), BruteForce(scans, T, h), 1e-12);
  // One robot's map imported into an empty map: a bitwise copy, stamps included.
  EXPECT_TRUE(SameTiles(*merge(*a, *TerrainMap::Create(p).value()), *a));
}

// The forgetting code path with no time passing is the path without it, bit for bit; with
// half_life_s = 0 stamps are ignored and tiles never stamped.
// Mutation checked: making Gain's product k * g rounded differently (k * (g * 1.0000001)) fails.
TEST(ForgettingTest, NoTimeOrNoHalfLifeIsBitwiseTheMapWithoutForgetting) {
  for (Method method :
       {Method::kBgkPlus, Method::kOneStep, Method::kBgkObstacle, Method::kBgkLocalLinear}) {
    SCOPED_TRACE(MethodName(method));
    MapParams off;
    off.method = method;
    MapParams on = off;
    on.half_life_s = 3.0;
    std::unique_ptr<TerrainMap> plain = TerrainMap::Create(off).value();
    std::unique_ptr<TerrainMap> stamped_off = TerrainMap::Create(off).value();
    std::unique_ptr<TerrainMap> same_time = TerrainMap::Create(on).value();
    for (int k = 0; k < 6; ++k) {
      const Eigen::Vector3d sensor(0.7 * k, 0.3 * k, 1.0);
      const std::vector<Point3f> pts = SampleSurface(RollingWithStep, sensor, 8.0, 3000, 10 + k);
      ASSERT_TRUE(plain->IntegrateScan(pts, At(sensor)).ok());
      ASSERT_TRUE(stamped_off->IntegrateScan(pts, At(sensor), false, (k + 1) * kSecond).ok());
      ASSERT_TRUE(same_time->IntegrateScan(pts, At(sensor), false, 42 * kSecond).ok());
    }
    EXPECT_TRUE(SameTiles(*plain, *stamped_off));
    stamped_off->ForEachTile([](TileKey, const Tile& t) { EXPECT_EQ(t.stamp_ns(), 0); });
    // Equal statistics; only the stamps differ.
    same_time->ForEachTile([&](TileKey key, const Tile& t) {
      EXPECT_EQ(t.stamp_ns(), 42 * kSecond);
      Tile copy(t);
      copy.set_stamp_ns(0);
      ASSERT_NE(plain->FindTile(key), nullptr);
      EXPECT_TRUE(copy == *plain->FindTile(key));
    });
    EXPECT_EQ(plain->tile_count(), same_time->tile_count());
  }
}

// With real sensor scans (free-space rays, caps, footprint), replaying the same stamped scans
// gives bitwise the same map, and time passing makes a once-seen place uncertain.
TEST(ForgettingTest, SensorScansReplayBitwiseAndOldEvidenceBecomesUncertain) {
  MapParams p;
  p.half_life_s = 1.0;
  p.sensor_height = 1.0;
  auto run = [&] {
    std::unique_ptr<TerrainMap> map = TerrainMap::Create(p).value();
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d sensor(0.5 * k, 0.0, 1.0);
      const std::vector<Point3f> pts = SampleSurface(RollingWithStep, sensor, 8.0, 3000, 20 + k);
      EXPECT_TRUE(map->IntegrateScan(pts, At(sensor), false, (k + 1) * kSecond / 10).ok());
    }
    return map;
  };
  const std::unique_ptr<TerrainMap> first = run();
  EXPECT_TRUE(SameTiles(*first, *run()));
  const CellEstimate fresh = first->EstimateAt(1.0, 1.0);
  EXPECT_EQ(fresh.state, CellState::kTraversable);
  // Twenty half-lives later a scan far away in the same tile ages it: the place is uncertain.
  std::unique_ptr<TerrainMap> later = run();
  const std::vector<Point3f> far = {{5.05f, 5.05f, 0.0f}};
  ASSERT_TRUE(later->IntegrateScan(far, Pose{}, true, 8 * kSecond / 10 + 20 * kSecond).ok());
  const CellEstimate old = later->EstimateAt(1.0, 1.0);
  EXPECT_NEAR(old.elevation_weight, fresh.elevation_weight * std::exp2(-20.0),
              1e-6 * fresh.elevation_weight * std::exp2(-20.0));
  EXPECT_GT(old.elevation_variance, p.variance_threshold);
  // Aged below half a full-kernel observation and failing only the variance: seen too little,
  // unknown (thin_evidence_weight); with the paper's state, non-traversable.
  EXPECT_EQ(old.block_reasons, kBlockedVariance);
  EXPECT_EQ(old.state, CellState::kUnknown);
  MapParams paper_state = p;
  paper_state.thin_evidence_weight = 0.0;
  paper_state.thin_ground_weight = 0.0;
  const Tile* t = later->FindTile(later->geometry().TileOf(later->geometry().CellAt(1.0, 1.0)));
  const int i = later->geometry().LocalIndex(later->geometry().CellAt(1.0, 1.0));
  EXPECT_EQ(EstimateCell(paper_state, t->w()[i], t->s()[i], t->q()[i], t->a()[i], t->b()[i]).state,
            CellState::kNonTraversable);
}

// A tile a scan only reads (its v's patch, its free-space rays) is read as of the scan's time:
// bringing those tiles to that time beforehand changes nothing the scan computes, bit for bit.
// With a prior (lambda > 0) an aged elevation moves toward prior_mean, so the reads matter.
// Mutations checked: the ray walk reading old tiles as if fresh (last_f = 1) fails it, and so
// does Elevation() doing so (f = 1).
TEST(ForgettingTest, TilesAScanOnlyReadsAreReadAsOfItsTime) {
  for (auto [method, block] :
       {std::pair{Method::kBgkPlus, true}, std::pair{Method::kBaseline, true},
        std::pair{Method::kBaseline, false}}) {
    SCOPED_TRACE(::testing::Message() << MethodName(method) << (block ? " block" : ""));
    MapParams p;
    p.method = method;
    p.half_life_s = 5.0;
    p.lambda = 0.1;
    // Without the block, a prior near the ground: aged cells are not contradicted, so nothing
    // brings tile (0, 0) to the scan's time and its patches are read aged.
    p.prior_mean = block ? -0.5 : 0.1;
    std::unique_ptr<TerrainMap> one = TerrainMap::Create(p).value();
    std::unique_ptr<TerrainMap> two = TerrainMap::Create(p).value();
    // A 1 m block in tile (0, 0) next to the border with tile (1, 0).
    auto surface = [block = block](double x, double y) {
      const bool in = block && x > 5.8 && x < 6.3 && y > 2.0 && y < 4.0;
      return RollingWithStep(x, y) + (in ? 1.0 : 0.0);
    };
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d sensor(3.2 + k, 3.2, 1.0);
      const std::vector<Point3f> pts = SampleSurface(surface, sensor, 8.0, 40000, 40 + k);
      for (TerrainMap* m : {one.get(), two.get()}) {
        ASSERT_TRUE(m->IntegrateScan(pts, At(sensor), false, (k + 1) * kSecond).ok());
      }
    }
    // 40.7 s (8.1 half-lives) later: ground returns only in a strip of tile (1, 0), the sensor over
    // tile (0, 0), so tile (0, 0) is crossed by rays (passing under the block's top as it was,
    // over it as it is now) and (baseline) read by patches near the border, not written.
    const Eigen::Vector3d sensor(5.5, 3.0, 1.0);
    std::vector<Point3f> strip;
    std::mt19937 rng(7);
    // bgk+ writes within l of a return, baseline only at it and reads within robot_radius.
    const double x0 = method == Method::kBaseline ? 6.45 : 6.8;
    std::uniform_real_distribution<double> ux(x0, 9.0), uy(0.5, 5.5);
    for (int i = 0; i < 20000; ++i) {
      const double x = ux(rng), y = uy(rng);
      strip.push_back({static_cast<float>(x - sensor.x()), static_cast<float>(y - sensor.y()),
                       static_cast<float>(RollingWithStep(x, y) - sensor.z())});
    }
    const int64_t t = 43 * kSecond + 7 * kSecond / 10;  // not whole half-lives: f is no power of 2
    const PreparedScan scan = PrepareScan(p, strip, At(sensor)).value();
    std::vector<TileKey> aged = scan.read_tiles;
    aged.insert(aged.end(), scan.clear_tiles.begin(), scan.clear_tiles.end());
    ASSERT_TRUE(std::find(aged.begin(), aged.end(), TileKey{0, 0}) != aged.end());
    for (const TileKey& k : aged) {
      if (Tile* tile = two->FindMutableTile(k)) two->integrator().Advance(*tile, t);
    }
    ASSERT_TRUE(one->IntegrateScan(strip, At(sensor), false, t).ok());
    ASSERT_TRUE(two->IntegrateScan(strip, At(sensor), false, t).ok());
    int compared = 0;
    one->ForEachTile([&](TileKey key, const Tile& tile) {
      Tile expected(tile);
      if (std::find(aged.begin(), aged.end(), key) != aged.end()) {
        one->integrator().Advance(expected, t);
      }
      ASSERT_NE(two->FindTile(key), nullptr);
      EXPECT_TRUE(expected == *two->FindTile(key)) << key.x << "," << key.y;
      ++compared;
    });
    EXPECT_EQ(compared, static_cast<int>(two->tile_count()));
  }
}

}  // namespace
}  // namespace bgkmap::testing
