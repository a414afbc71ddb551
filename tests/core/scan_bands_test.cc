// A scan integrated in bands on several threads (core/scan_bands.h) changes the map exactly as
// the whole scan does: every tile, bit for bit, with its version and stamp, and the same report
// of changed tiles and blocks. Scans that clear a vanished obstacle (free-space rays), a
// vehicle's box footprint and forgetting are among them.
#include "bgkmap/core/scan_bands.h"

#include <gtest/gtest.h>

#include <cctype>
#include <functional>
#include <string>
#include <thread>

#include "bgkmap/core/cell_estimate.h"
#include "synthetic_terrain.h"

namespace bgkmap {
namespace {

// Rolling ground; while `boxes`, a row of 0.6 m boxes 0.8 m long every 1.5 m along x, |y| < 1
// (parked cars that then drive off: wherever a band's border falls, rays clear one near it).
testing::Surface Ground(bool boxes) {
  return [boxes](double x, double y) {
    const bool in_box = boxes && std::fmod(x + 30.0, 1.5) < 0.8 && std::abs(y) < 1.0;
    return testing::RollingWithStep(x, y) + (in_box ? 0.6 : 0.0);
  };
}

struct Case {
  Method method;
  bool forgetting_and_box;  // half_life_s and a footprint box
  bool transients = false;  // transient objects: the boxes appear on seen ground, then go
};

MapParams ParamsFor(const Case& c) {
  MapParams p;
  p.resolution = 0.1;
  p.tile_size = 8;  // many tiles across the halo (31 cells), so that bands cut between them
  p.method = c.method;
  p.sensor_height = 1.0;
  if (c.forgetting_and_box) {
    p.half_life_s = 2.0;
    p.footprint_length = 2.0;
    p.footprint_width = 1.0;
  }
  if (c.transients) {
    p.transient_confirm_s = 2.0;
    p.transient_expire_s = 0.5;
  }
  return p;
}

// With transient objects: from scan 2 on, a car 1.3 m tall and 0.5 m wide (narrower than these
// 0.8 m tiles, so that the tiles of its trail still hold returns beside it) follows the sensor 3 m
// behind it on its track and hides the ground behind itself (no return there): the road it leaves
// is seen again by no scan, and whether it is hidden is read from returns metres from it, across
// bands.
std::vector<Point3f> WithCarBehind(const Eigen::Vector3d& o, int s) {
  if (s < 2) return testing::SampleSurface(Ground(false), o, 7.0, 9000, 300 + s);
  const Eigen::Vector2d track = Eigen::Vector2d(0.7, 0.2).normalized();
  const Eigen::Vector2d car = o.head<2>() - 3.0 * track;
  const double x0 = car.x() - 0.6, x1 = car.x() + 0.6, y0 = car.y() - 0.25, y1 = car.y() + 0.25;
  const auto in_car = [&](double x, double y) { return x > x0 && x < x1 && y > y0 && y < y1; };
  const auto surface = [&](double x, double y) {
    return testing::RollingWithStep(x, y) + (in_car(x, y) ? 1.3 : 0.0);
  };
  // The segment from the sensor to (x, y) crosses the car's box (slabs): the car, taller than the
  // sensor, hides the point.
  const auto behind_car = [&](double x, double y) {
    double lo = 0.0, hi = 1.0;
    const double d[2] = {x - o.x(), y - o.y()}, a[2] = {o.x(), o.y()};
    const double min[2] = {x0, y0}, max[2] = {x1, y1};
    for (int i = 0; i < 2; ++i) {
      if (d[i] == 0.0) {
        if (a[i] < min[i] || a[i] > max[i]) return false;
        continue;
      }
      double t0 = (min[i] - a[i]) / d[i], t1 = (max[i] - a[i]) / d[i];
      if (t0 > t1) std::swap(t0, t1);
      lo = std::max(lo, t0);
      hi = std::min(hi, t1);
    }
    return lo < hi;
  };
  std::vector<Point3f> pts;
  for (const Point3f& q : testing::SampleSurface(surface, o, 7.0, 9000, 300 + s)) {
    const double x = o.x() + q.x, y = o.y() + q.y;
    if (in_car(x, y) || !behind_car(x, y)) pts.push_back(q);
  }
  return pts;
}

// Six scans 0.3 s apart, the boxes in the first two; with transient objects ten, a car following
// the sensor from the third on.
std::vector<PreparedScan> MakeScans(const MapParams& p) {
  std::vector<PreparedScan> scans;
  const bool transients = p.transient_confirm_s > 0;
  for (int s = 0; s < (transients ? 10 : 6); ++s) {
    const Eigen::Vector3d origin(0.7 * s, 0.2 * s, 1.0);
    const auto points = transients
                            ? WithCarBehind(origin, s)
                            : testing::SampleSurface(Ground(s < 2), origin, 7.0, 9000, 300 + s);
    PreparedScan scan = std::move(PrepareScan(p, points, testing::At(origin))).value();
    scan.stamp_ns = 1'000'000'000 + s * 300'000'000LL;
    scans.push_back(std::move(scan));
  }
  return scans;
}

void ExpectSameTiles(const TerrainMap& a, const TerrainMap& b) {
  EXPECT_EQ(a.tile_count(), b.tile_count());
  a.ForEachTile([&](TileKey key, const Tile& ta) {
    const Tile* tb = b.FindTile(key);
    ASSERT_NE(tb, nullptr) << key.x << "," << key.y;
    EXPECT_TRUE(ta == *tb) << "tile " << key.x << "," << key.y;
    EXPECT_EQ(ta.version(), tb->version()) << key.x << "," << key.y;
  });
}

// Runs each task on a thread of its own.
void OnThreads(std::span<const std::function<void()>> tasks) {
  std::vector<std::thread> threads;
  for (const std::function<void()>& task : tasks) threads.emplace_back(task);
  for (std::thread& t : threads) t.join();
}

// Integrates `scan` into `map` in `bands`, one thread each; returns the merged report.
ScanReport IntegrateInBands(TerrainMap& map, const PreparedScan& scan, uint64_t version,
                            const std::vector<TileBand>& bands) {
  const TileWindow whole = map.MakeWindow(scan);
  std::optional<ScanReport> report =
      bgkmap::IntegrateInBands(map, scan, whole, bands, version, OnThreads);
  EXPECT_TRUE(report.has_value());
  return report ? std::move(*report) : ScanReport{};
}

// Integrates every scan whole into one map and in bands into another and compares them. `cut`
// gives a scan's bands.
void ExpectBandsChangeAsTheWhole(
    const MapParams& p, const std::function<std::vector<TileBand>(const PreparedScan&)>& cut) {
  const std::vector<PreparedScan> scans = MakeScans(p);
  auto whole = std::move(TerrainMap::Create(p)).value();
  auto banded = std::move(TerrainMap::Create(p)).value();
  uint64_t contradicted = 0;
  size_t most_pending = 0;
  int restored = 0;  // cells a scan made traversable again where they were pending and blocked
  for (size_t k = 0; k < scans.size(); ++k) {
    const TileWindow window = whole->MakeWindow(scans[k]);
    std::vector<std::pair<TileKey, int>> blocked_pending;
    whole->ForEachTile([&](TileKey key, const Tile& tile) {
      for (const Tile::PendingGround& g : tile.pending()) {
        const Tile::CellStats c = tile.CellAt(g.local);
        if (EstimateCell(p, c.w, c.s, c.q, c.a, c.b).state == CellState::kNonTraversable)
          blocked_pending.emplace_back(key, g.local);
      }
    });
    const ScanReport expected = whole->Integrate(scans[k], window, k + 1);
    for (const auto& [key, local] : blocked_pending) {
      const Tile::CellStats c = whole->FindTile(key)->CellAt(local);
      restored += EstimateCell(p, c.w, c.s, c.q, c.a, c.b).state == CellState::kTraversable;
    }
    size_t pending = 0;
    whole->ForEachTile([&](TileKey, const Tile& tile) { pending += tile.pending().size(); });
    most_pending = std::max(most_pending, pending);
    contradicted += expected.contradicted_cells;
    const ScanReport got = IntegrateInBands(*banded, scans[k], k + 1, cut(scans[k]));
    EXPECT_EQ(got.changed_tiles, expected.changed_tiles) << "scan " << k;
    EXPECT_EQ(got.changed_blocks, expected.changed_blocks) << "scan " << k;
    EXPECT_EQ(got.observed_cells, expected.observed_cells);
  }
  EXPECT_GT(contradicted, 0u) << "no free-space ray cleared a vanished box";
  if (p.transient_confirm_s > 0) {
    EXPECT_GT(most_pending, 0u) << "no ground was kept aside";
    EXPECT_GT(restored, 0) << "no hidden trail was given back";
  }
  ExpectSameTiles(*whole, *banded);
}

class ScanBandsTest : public ::testing::TestWithParam<Case> {};

TEST_P(ScanBandsTest, BandsOfTheCutChangeTheMapAsTheWholeScan) {
  const MapParams p = ParamsFor(GetParam());
  for (const int count : {2, 3, 5}) {
    size_t most_bands = 0;
    ExpectBandsChangeAsTheWhole(p, [&](const PreparedScan& scan) {
      std::vector<TileBand> bands = CutScansIntoBands(p, {&scan, 1}, count);
      most_bands = std::max(most_bands, bands.size());
      return bands;
    });
    EXPECT_EQ(most_bands, static_cast<size_t>(count)) << "the cut made fewer bands than asked";
  }
}

// The cut puts its borders where the cells are densest, near the sensor, where rays are high;
// borders far from it are crossed low by the rays of returns beyond them, which clear a box on
// the other side (a halo without the rays' reach fails here).
TEST_P(ScanBandsTest, BandsCutAnywhereChangeTheMapAsTheWholeScan) {
  const MapParams p = ParamsFor(GetParam());
  for (const std::vector<int64_t>& borders :
       std::vector<std::vector<int64_t>>{{56}, {-40}, {-48, 24, 64}}) {
    for (const bool along_x : {true, false}) {
      ExpectBandsChangeAsTheWhole(
          p, [&](const PreparedScan&) { return BandsBetween(borders, along_x); });
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, ScanBandsTest,
                         ::testing::Values(Case{Method::kBgkPlus, false},
                                           Case{Method::kBgkPlus, true},
                                           Case{Method::kBgkLocalLinear, false},
                                           Case{Method::kBgkObstacle, true},
                                           Case{Method::kBgkPlus, true, true}),
                         [](const ::testing::TestParamInfo<Case>& param_info) {
                           std::string name;
                           for (char ch : MethodName(param_info.param.method)) {
                             if (std::isalnum(static_cast<unsigned char>(ch))) name += ch;
                             if (ch == '+') name += "plus";
                           }
                           return name +
                                  (param_info.param.forgetting_and_box ? "ForgettingBox" : "") +
                                  (param_info.param.transients ? "Transients" : "");
                         });

TEST(ScanBandsTest, OneBandWhenThereIsNothingToCut) {
  MapParams p;
  const PreparedScan empty;
  EXPECT_TRUE(CutScansIntoBands(p, {&empty, 1}, 4).front().IsWholeMap());
  const std::vector<PreparedScan> scans = MakeScans(p);
  EXPECT_EQ(CutScansIntoBands(p, scans, 1).size(), 1u);
}

}  // namespace
}  // namespace bgkmap
