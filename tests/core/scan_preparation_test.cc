#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <thread>

#include "bgkmap/core/point_filter.h"
#include "bgkmap/core/scan.h"

namespace bgkmap {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(ScanPreparationTest, BinsPointsIntoCellsWithMaxOrMean) {
  MapParams p;
  p.min_range = 0.0;
  const std::vector<Point3f> pts = {
      {0.51f, 0.52f, -1.0f}, {0.55f, 0.58f, -0.5f}, {-0.05f, 0.0f, -2.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s->cells.size(), 2u);
  // Sorted by (x, y): cell (-1, 0) first, then (5, 5).
  EXPECT_EQ(s->cells[0].cell, (CellIndex{-1, 0}));
  EXPECT_EQ(s->cells[1].cell, (CellIndex{5, 5}));
  EXPECT_DOUBLE_EQ(s->cells[1].y, -0.5);
  p.observation = Observation::kMean;
  s = PrepareScan(p, pts, Pose{});
  EXPECT_DOUBLE_EQ(s->cells[1].y, -0.75);
}

// The cells come out in (x, y) order, one per cell, each the max (or the mean, summed in the
// points' order) of its own points, whatever the box's size: a street-sized scan sorts in two
// digits of the radix sort, a stray point 20 km away widens the box to three and more.
TEST(ScanPreparationTest, CellsAreSortedAndReducedAsANaiveReductionWouldHaveThem) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> near(-60.0f, 60.0f),
      height(-3.0f, 0.4f);  // below max_height_above_sensor
  std::vector<Point3f> pts;
  for (int i = 0; i < 20000; ++i) pts.push_back({near(rng), near(rng), height(rng)});
  for (int i = 0; i < 2000; ++i) pts.push_back({pts[i].x, pts[i].y, height(rng)});  // repeats
  MapParams p;
  p.min_range = 0.0;
  p.max_range = 1e6;
  for (const bool stray : {false, true}) {
    std::vector<Point3f> in = pts;
    if (stray) in.push_back({-20000.0f, 15000.0f, -1.0f});
    for (const Observation mode : {Observation::kMax, Observation::kMean}) {
      p.observation = mode;
      std::map<std::pair<int, int>, std::vector<double>> naive;
      const double inv_res = 1.0 / p.resolution;  // PrepareScan's binning
      for (const Point3f& q : in) {
        naive[{static_cast<int>(std::floor(double{q.x} * inv_res)),
               static_cast<int>(std::floor(double{q.y} * inv_res))}]
            .push_back(static_cast<double>(q.z));
      }
      Result<PreparedScan> s = PrepareScan(p, in, Pose{});
      ASSERT_TRUE(s.ok());
      ASSERT_EQ(s->cells.size(), naive.size());
      size_t k = 0;
      for (const auto& [cell, zs] : naive) {
        const ObservedCell& c = s->cells[k++];
        ASSERT_EQ(c.cell, (CellIndex{cell.first, cell.second}));
        double y = zs.front(), sum = 0.0;
        for (double z : zs) {
          y = std::max(y, z);
          sum += z;
        }
        if (mode == Observation::kMean) y = sum / static_cast<double>(zs.size());
        ASSERT_EQ(c.y, y) << "cell " << cell.first << ", " << cell.second;
      }
    }
  }
}

TEST(ScanPreparationTest, TransformsByThePose) {
  MapParams p;
  p.min_range = 0.0;
  Pose pose = Pose::FromQuaternion(std::cos(M_PI / 4), 0, 0, std::sin(M_PI / 4), 10, 20, 2);
  const std::vector<Point3f> pts = {{1.05f, 0.03f, -2.0f}};  // 90 deg yaw: (x, y) -> (-y, x)
  Result<PreparedScan> s = PrepareScan(p, pts, pose);
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s->cells.size(), 1u);
  EXPECT_EQ(s->cells[0].cell, (CellIndex{99, 210}));  // map point (9.97, 21.05)
  EXPECT_NEAR(s->cells[0].y, 0.0, 1e-6);
}

TEST(ScanPreparationTest, DropsAndCountsEveryKindOfBadPoint) {
  MapParams p;  // min_range 1, max_range 100, max_height_above_sensor 0.5
  const std::vector<Point3f> pts = {
      {5, 0, -1},                                     // kept
      {kNaN, 0, 0},     {0, kInf, 0}, {0, 0, -kInf},  // non-finite
      {0.2f, 0, -0.1f},                               // too close
      {200, 0, -1},                                   // too far
      {5, 0, 3},                                      // above the sensor: overhang
  };
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.input, 7u);
  EXPECT_EQ(s->counts.kept, 1u);
  EXPECT_EQ(s->counts.dropped_nonfinite, 3u);
  EXPECT_EQ(s->counts.dropped_range, 2u);
  EXPECT_EQ(s->counts.dropped_height, 1u);
  EXPECT_EQ(s->cells.size(), 1u);
}

// FilterSensorPoint is PrepareScan's filter to the last bit: points on either side of each
// limit, under a tilted pose, decide alike, and the scan of only the kept points prepares to the
// same cells. Catches a predicate that compares |p| instead of |p|^2, or the height before the
// rotation.
TEST(ScanPreparationTest, FilterSensorPointDecidesAsPrepareScan) {
  MapParams p;
  p.footprint_length = 2.2;  // a self-filter box whose faces cut the spheres below
  p.footprint_width = 1.6;
  p.footprint_sensor_x = -0.3;
  p.self_filter_below = 0.2;
  p.self_filter_margin = 0.05;
  const Pose pose = Pose::FromQuaternion(0.995, 0.05, -0.08, 0.02, 3, -4, 1.7);
  std::vector<Point3f> pts = {{kNaN, 0, 0}, {0, 0, kInf}};
  for (float r : {0.999999f, 1.0f, 1.000001f, 99.99999f, 100.0f, 100.00001f}) {
    for (float z : {-1.0f, 0.0f, 0.2f, 0.4f, 0.45f, 0.5f, 0.55f, 0.6f, 3.0f}) {
      for (float a : {0.0f, 0.7f, 2.1f, 3.5f, 5.0f}) {
        const float h = std::sqrt(std::max(r * r - z * z, 0.0f));
        pts.push_back({h * std::cos(a), h * std::sin(a), z});
      }
    }
  }
  ScanPointCounts counts;
  std::vector<Point3f> kept;
  for (const Point3f& q : pts) {
    switch (FilterSensorPoint(p, pose, q)) {
      case PointFilter::kNonFinite:
        ++counts.dropped_nonfinite;
        break;
      case PointFilter::kRange:
        ++counts.dropped_range;
        break;
      case PointFilter::kHeight:
        ++counts.dropped_height;
        break;
      case PointFilter::kKept:
        kept.push_back(q);
        break;
    }
  }
  Result<PreparedScan> all = PrepareScan(p, pts, pose);
  Result<PreparedScan> some = PrepareScan(p, kept, pose);
  ASSERT_TRUE(all.ok() && some.ok());
  EXPECT_EQ(all->counts.dropped_nonfinite, counts.dropped_nonfinite);
  EXPECT_EQ(all->counts.dropped_range, counts.dropped_range);
  EXPECT_EQ(all->counts.dropped_height, counts.dropped_height);
  EXPECT_GT(counts.dropped_range, 0u);
  EXPECT_GT(counts.dropped_height, 0u);
  EXPECT_EQ(all->counts.kept, kept.size());
  ASSERT_EQ(all->cells.size(), some->cells.size());
  for (size_t i = 0; i < all->cells.size(); ++i) {
    EXPECT_EQ(all->cells[i].cell, some->cells[i].cell);
    EXPECT_EQ(all->cells[i].y, some->cells[i].y);  // bitwise
  }
}

// The self-filter drops what lies in the robot's own box (the footprint box grown by the margin,
// in the sensor's frame, above self_filter_below under the sensor) and nothing else; off without
// the footprint box or with self_filter_below 0; in the map frame never.
TEST(ScanPreparationTest, SelfFilterDropsTheBodyBoxOnly) {
  MapParams p;
  p.min_range = 0.5;
  p.footprint_length = 4.0;
  p.footprint_width = 2.0;
  p.footprint_sensor_x = 0.5;  // the box's centre 0.5 m behind the sensor: x in [-2.6, 1.6]
  p.self_filter_below = 1.5;
  p.self_filter_margin = 0.1;  // y in [-1.1, 1.1]
  const std::vector<Point3f> body = {{1.5f, 0.5f, -1.0f}, {-2.5f, -1.05f, -1.45f}, {0, 1.0f, 0.3f}};
  const std::vector<Point3f> world = {{1.7f, 0.5f, -1.0f},  {-2.7f, 0.0f, -1.0f},
                                      {0.8f, 1.2f, -1.0f},  {0.8f, 0.0f, -1.6f},
                                      {10.0f, 0.0f, -1.7f}, {0.0f, -3.0f, -1.7f}};
  std::vector<Point3f> pts = body;
  pts.insert(pts.end(), world.begin(), world.end());
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.dropped_range, body.size());
  EXPECT_EQ(s->counts.kept, world.size());
  for (const Point3f& q : body) EXPECT_EQ(FilterSensorPoint(p, Pose{}, q), PointFilter::kRange);
  for (const Point3f& q : world) EXPECT_EQ(FilterSensorPoint(p, Pose{}, q), PointFilter::kKept);

  MapParams no_box = p;
  no_box.footprint_width = 0;  // no footprint box: the self-filter is off
  MapParams off = p;
  off.self_filter_below = 0;
  for (const MapParams& q : {no_box, off}) {
    Result<PreparedScan> t = PrepareScan(q, pts, Pose{});
    ASSERT_TRUE(t.ok());
    EXPECT_EQ(t->counts.dropped_range, 0u);
  }
  Result<PreparedScan> in_map = PrepareScan(p, pts, Pose{}, /*frame_is_map=*/true);
  ASSERT_TRUE(in_map.ok());
  EXPECT_EQ(in_map->counts.kept, pts.size());
}

TEST(ScanPreparationTest, FrameIsMapSkipsSensorFilters) {
  MapParams p;
  const std::vector<Point3f> pts = {{0.0f, 0.0f, 50.0f}, {500.0f, 0.0f, 0.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{}, /*frame_is_map=*/true);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.kept, 2u);
}

TEST(ScanPreparationTest, PointsBeyondTheCellRangeAreDroppedNotWrapped) {
  MapParams p;
  p.max_range = 1e12;
  const std::vector<Point3f> pts = {{1e9f, 0, -1}, {5, 0, -1}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->counts.dropped_out_of_bounds, 1u);
  EXPECT_EQ(s->counts.kept, 1u);
}

TEST(ScanPreparationTest, RejectsNonRigidAndNonFinitePoses) {
  const MapParams p;
  const std::vector<Point3f> pts = {{5, 0, -1}};
  Pose scaled;
  scaled.rotation *= 1.01;
  Result<PreparedScan> s = PrepareScan(p, pts, scaled);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("orthonormal"), std::string::npos) << s.status().message();

  Pose reflected;
  reflected.rotation(2, 2) = -1;  // orthonormal but det -1
  EXPECT_FALSE(PrepareScan(p, pts, reflected).ok());

  Pose nan_pose;
  nan_pose.translation.x() = std::nan("");
  s = PrepareScan(p, pts, nan_pose);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("finite"), std::string::npos);

  Pose far;
  far.translation.x() = 1e12;
  s = PrepareScan(p, pts, far);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), Status::Code::kOutOfRange);
}

TEST(ScanPreparationTest, FootprintCoversKernelSupportAcrossTileBorders) {
  MapParams p;  // l = 0.3 (2 cells reach), tile 64
  p.min_range = 0;
  // One point in cell (63, 0): the kernel reaches cells 61..65, so tiles (0,-1), (0,0), (1,-1),
  // (1,0) are candidates; the corner ones are beyond reach? (64, -1) is at offset (1, -1): yes.
  const std::vector<Point3f> pts = {{6.35f, 0.05f, -1.0f}};
  Result<PreparedScan> s = PrepareScan(p, pts, Pose{});
  ASSERT_TRUE(s.ok());
  const std::vector<TileKey> expected = {{0, -1}, {0, 0}, {1, -1}, {1, 0}};
  EXPECT_EQ(s->write_tiles, expected);
  // Far from borders: a single tile.
  s = PrepareScan(p, std::vector<Point3f>{{3.25f, 3.25f, -1.0f}}, Pose{});
  EXPECT_EQ(s->write_tiles, (std::vector<TileKey>{{0, 0}}));
}

std::vector<TileKey> Union(std::vector<TileKey> a, const std::vector<TileKey>& b) {
  a.insert(a.end(), b.begin(), b.end());
  std::sort(a.begin(), a.end());
  a.erase(std::unique(a.begin(), a.end()), a.end());
  return a;
}

// A scan's tile lists are the union of its points' own: what it writes, what it may change
// (writes and rays' clears) and everything it touches (and reads), sorted and without repeats,
// for points near the sensor, across tile borders, at negative coordinates, and for a cloud
// spread over 200 km (too wide a box of tiles to flag: the lists take another path).
TEST(ScanPreparationTest, TileListsAreTheUnionOfThePointsOwn) {
  MapParams p;
  p.dynamics = Dynamics::kOn;
  p.min_range = 0;
  p.max_range = 1e6;
  p.max_height_above_sensor = 1e6;
  Pose pose;
  pose.translation = {0.3, -0.2, 1.5};
  const std::vector<std::vector<Point3f>> clouds = {
      {{6.35f, 0.05f, -1.0f}, {-6.41f, -12.8f, -1.2f}, {0.5f, 0.5f, -1.4f}, {25.6f, -6.4f, 0}},
      {{6.35f, 0.05f, -1.0f}, {-99999.0f, -99999.0f, 0}, {99999.0f, 99999.0f, 0}}};
  for (const std::vector<Point3f>& pts : clouds) {
    Result<PreparedScan> whole = PrepareScan(p, pts, pose);
    ASSERT_TRUE(whole.ok());
    ASSERT_EQ(whole->counts.kept, pts.size());
    std::vector<TileKey> writes, changeable, touched;
    for (const Point3f& pt : pts) {
      Result<PreparedScan> one = PrepareScan(p, std::vector<Point3f>{pt}, pose);
      ASSERT_TRUE(one.ok());
      writes = Union(writes, one->write_tiles);
      changeable = Union(changeable, one->ChangeableTiles());
      touched = Union(Union(touched, one->ChangeableTiles()), one->read_tiles);
    }
    EXPECT_EQ(whole->write_tiles, writes);
    EXPECT_EQ(whole->ChangeableTiles(), changeable);
    EXPECT_EQ(Union(whole->ChangeableTiles(), whole->read_tiles), touched);
    EXPECT_TRUE(std::is_sorted(whole->read_tiles.begin(), whole->read_tiles.end()));
    EXPECT_TRUE(std::is_sorted(whole->clear_tiles.begin(), whole->clear_tiles.end()));
  }
}

// The preparation keeps its buffers per thread between scans and frees those a huge scan grew
// (core/src/scratch_buffer.h): a thread's scans come out as a fresh thread's would, whatever
// came before, a 1.2 M-point scan (beyond what is kept) included. Mutation checked: the binned
// points not cleared before the next scan (the second preparation then differs).
TEST(ScanPreparationTest, AThreadsEarlierScansChangeNothing) {
  MapParams p;
  p.min_range = 0.0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> xy(-40.0f, 40.0f), z(-2.0f, 1.0f);
  auto cloud = [&](size_t n) {
    std::vector<Point3f> pts(n);
    for (Point3f& q : pts) q = {xy(rng), xy(rng), z(rng)};
    return pts;
  };
  const std::vector<Point3f> small = cloud(20'000), huge = cloud(1'200'000), mid = cloud(300'000);
  const Pose pose = Pose::FromQuaternion(1, 0, 0, 0, 3, -2, 1.5);
  auto prepare = [&](const std::vector<Point3f>& pts) {
    Result<PreparedScan> s = PrepareScan(p, pts, pose);
    EXPECT_TRUE(s.ok());
    return std::move(s).value();
  };
  auto same = [](const PreparedScan& a, const PreparedScan& b) {
    if (a.cells.size() != b.cells.size() || a.write_tiles != b.write_tiles) return false;
    for (size_t i = 0; i < a.cells.size(); ++i) {
      if (a.cells[i].cell != b.cells[i].cell || a.cells[i].y != b.cells[i].y) return false;
    }
    return true;
  };
  // Each scan on a thread of its own: nothing kept from before.
  std::vector<PreparedScan> fresh(3);
  std::thread([&] { fresh[0] = prepare(small); }).join();
  std::thread([&] { fresh[1] = prepare(huge); }).join();
  std::thread([&] { fresh[2] = prepare(mid); }).join();
  ASSERT_GT(fresh[1].cells.size(), 500'000u);
  // One thread, one after the other, the small scan again after the buffers were freed.
  EXPECT_TRUE(same(prepare(mid), fresh[2]));
  EXPECT_TRUE(same(prepare(small), fresh[0]));
  EXPECT_TRUE(same(prepare(huge), fresh[1]));
  EXPECT_TRUE(same(prepare(small), fresh[0]));
  EXPECT_TRUE(same(prepare(mid), fresh[2]));
}

}  // namespace
}  // namespace bgkmap
