// A served map equals the offline map of the same scans.
#include <gtest/gtest.h>
#include <sched.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "../../core/stride_oracle.h"
#include "bgkmap/core/path_check.h"
#include "bgkmap/core/path_sweep.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

class ServedMapTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fixture_ = new ServerFixture();
    std::vector<ScanData> scans;
    for (const OwnedScan& s : StreetScans()) scans.push_back(s.Data());
    ASSERT_EQ(scans.size(), 3u);
    RpcResult<std::vector<ScanAck>> acks = fixture_->client().IngestAll(scans);
    ASSERT_TRUE(acks.ok()) << acks.status().ToString();
    acks_ = *acks;
    std::vector<const OwnedScan*> order;
    for (const OwnedScan& s : StreetScans()) order.push_back(&s);
    offline_ = OfflineMap(order).release();
  }
  static void TearDownTestSuite() {
    delete fixture_;
    delete offline_;
  }
  static ServerFixture* fixture_;
  static TerrainMap* offline_;
  static std::vector<ScanAck> acks_;
};

ServerFixture* ServedMapTest::fixture_ = nullptr;
TerrainMap* ServedMapTest::offline_ = nullptr;
std::vector<ScanAck> ServedMapTest::acks_;

// bgk-ll through the real server: the plane moments are integrated by the serving path and read
// by region queries exactly as the offline engine does.
TEST(ServedMapBgkLlTest, ServedMapAndRegionEqualTheOfflineMap) {
  ServerConfig config = TestConfig();
  config.map.method = Method::kBgkLocalLinear;
  ServerFixture fixture(config);
  std::vector<ScanData> scans;
  std::vector<const OwnedScan*> order;
  for (const OwnedScan& s : StreetScans()) {
    scans.push_back(s.Data());
    order.push_back(&s);
  }
  RpcResult<std::vector<ScanAck>> acks = fixture.client().IngestAll(scans);
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
  const std::unique_ptr<TerrainMap> offline = OfflineMap(order, config.map);
  int planes = 0;
  offline->ForEachTile([&](TileKey, const Tile& t) { planes += t.has_plane(); });
  EXPECT_EQ(planes, static_cast<int>(offline->tile_count()));
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(), *offline));
  const MetricBox box = KnownBox(*offline);
  RpcResult<Raster> served = fixture.client().QueryRegion({box, {}, 1}, nullptr);
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  EXPECT_TRUE(RastersMatch(*served, OfflineRegion(*offline, box, 1), 1e-5));
}

TEST_F(ServedMapTest, EveryScanAppliedInOrderWithItsCounts) {
  ASSERT_EQ(acks_.size(), 3u);
  for (size_t i = 0; i < acks_.size(); ++i) {
    EXPECT_EQ(acks_[i].status, AckStatus::kApplied) << acks_[i].error.ToString();
    EXPECT_EQ(acks_[i].sequence, i + 1);
    EXPECT_EQ(acks_[i].map_version, i + 1);
    EXPECT_EQ(acks_[i].counts.input, StreetScans()[i].points.size());
    EXPECT_GT(acks_[i].counts.kept, acks_[i].counts.input / 2);
    EXPECT_FALSE(acks_[i].changed_tiles.empty());
    EXPECT_TRUE(std::is_sorted(acks_[i].changed_tiles.begin(), acks_[i].changed_tiles.end()));
  }
}

TEST_F(ServedMapTest, SnapshotIsBitwiseTheOfflineMap) {
  EXPECT_TRUE(MapsEqual(*fixture_->server().SnapshotMap(), *offline_));
}

TEST_F(ServedMapTest, RegionQueryEqualsOfflineRaster) {
  const MetricBox box = KnownBox(*offline_);
  uint64_t version = 0;
  RpcResult<Raster> served = fixture_->client().QueryRegion({box, {}, 1}, &version);
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  EXPECT_EQ(version, 3u);
  const Raster offline = OfflineRegion(*offline_, box, 1);
  EXPECT_TRUE(RastersMatch(*served, offline, 1e-5));
  // Several chunks were needed (the default chunk is 1 MiB).
  EXPECT_GT(served->rows * served->cols * 6 * 4, 1 << 20);
}

TEST_F(ServedMapTest, CoarseRegionEqualsOfflineStrideAggregation) {
  MetricBox box = KnownBox(*offline_);
  box.min_x += 0.37;  // not aligned: the server widens to the global stride grid
  for (int stride : {3, 8}) {
    RpcResult<Raster> served = fixture_->client().QueryRegion({box, {}, stride});
    ASSERT_TRUE(served.ok()) << served.status().ToString();
    EXPECT_EQ(served->box.min.x % stride, 0);
    EXPECT_EQ((served->box.max.y + 1) % stride, 0);
    EXPECT_NEAR(served->resolution, 0.1 * stride, 1e-12);
    EXPECT_TRUE(RastersMatch(*served, OfflineRegion(*offline_, box, stride), 1e-5));
    // And against an answer not computed by ExtractRaster: the brute-force stride rule of
    // docs/semantics.md on the offline map's cells (tests/core/stride_oracle.h). Mutation
    // checked: keeping the last cell's variance instead of the block's worst (core/src/raster.cc)
    // fails here, while the comparison above with OfflineRegion still passes.
    EXPECT_TRUE(
        RastersMatch(*served, StrideOracle(*offline_, served->box, served->layers, stride), 1e-5));
  }
}

TEST_F(ServedMapTest, LayerSubsetInRequestedOrder) {
  const MetricBox box{-10, -10, 10, 10};
  RpcResult<Raster> served =
      fixture_->client().QueryRegion({box, {Layer::kTraversability, Layer::kElevation}, 1});
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  ASSERT_EQ(served->layers.size(), 2u);
  EXPECT_EQ(served->layers[0], Layer::kTraversability);
  const Raster all = OfflineRegion(*offline_, box, 1);
  EXPECT_EQ(served->cols, 200);
  EXPECT_EQ(served->rows, 200);
  const std::vector<float>& want = *all.Find(Layer::kTraversability);
  ASSERT_EQ(served->data[0].size(), want.size());
  EXPECT_EQ(0, std::memcmp(served->data[0].data(), want.data(), want.size() * sizeof(float)));
}

TEST_F(ServedMapTest, PointQueryEqualsOfflineEstimates) {
  std::vector<std::array<double, 2>> points;
  for (double x = -30; x <= 30; x += 0.73) {
    for (double y = -30; y <= 30; y += 1.91) points.push_back({x, y});
  }
  RpcResult<PointValues> served = fixture_->client().QueryPoints(points);
  ASSERT_TRUE(served.ok()) << served.status().ToString();
  ASSERT_EQ(served->layers.size(), static_cast<size_t>(kLayerCount));
  size_t known = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const CellEstimate e = offline_->EstimateAt(points[i][0], points[i][1]);
    for (size_t j = 0; j < served->layers.size(); ++j) {
      const float want = e.Get(served->layers[j]);
      const float got = served->at(i, j);
      if (std::isnan(want)) {
        EXPECT_TRUE(std::isnan(got));
      } else {
        EXPECT_FLOAT_EQ(got, want);
      }
    }
    known += !std::isnan(e.elevation);
  }
  EXPECT_GT(known, points.size() / 4);
}

TEST_F(ServedMapTest, InfoDescribesTheMap) {
  RpcResult<MapInfo> info = fixture_->client().Info();
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->map_version, 3u);
  EXPECT_EQ(info->scans_applied, 3u);
  EXPECT_EQ(info->known_cells, static_cast<uint64_t>(offline_->CountKnownCells()));
  EXPECT_EQ(info->tile_count, offline_->tile_count());
  EXPECT_EQ(info->known_cells_box, offline_->KnownBounds());
  EXPECT_EQ(info->params.resolution, 0.1);
  EXPECT_EQ(info->params.tile_size, 64);
  EXPECT_EQ(info->params.method, Method::kBgkPlus);
  EXPECT_NE(info->params_yaml.find("kernel_length"), std::string::npos);
  ASSERT_EQ(info->robots.size(), 1u);
  EXPECT_EQ(info->robots[0].robot_id, "street");
  EXPECT_EQ(info->robots[0].last_sequence, 3u);
  EXPECT_EQ(info->robots[0].scans_applied, 3u);
  EXPECT_EQ(info->limits.max_region_cells, 4'000'000u);
}

TEST_F(ServedMapTest, PathCheckFindsTheWorstCellUnderTheFootprint) {
  PathQuery q;
  for (double x = -5; x <= 5; x += 0.5) q.poses.push_back({x, 0.0, 0.0});
  q.radius = 0.5;
  q.max_unknown_fraction = 1.0;
  RpcResult<PathCheck> check = fixture_->client().CheckPath(q);
  ASSERT_TRUE(check.ok()) << check.status().ToString();
  ASSERT_EQ(check->poses.size(), q.poses.size());
  const double r = 0.1;
  for (size_t i = 0; i < q.poses.size(); ++i) {
    // Recompute from the offline map.
    float worst = std::nanf("");
    int cells = 0, unknown = 0;
    for (int iy = -10; iy <= 10; ++iy) {
      for (int ix = -10; ix <= 10; ++ix) {
        const CellIndex c = offline_->geometry().CellAt(q.poses[i].x, q.poses[i].y);
        const CellIndex cell{c.x + ix, c.y + iy};
        const double cx = (cell.x + 0.5) * r - q.poses[i].x, cy = (cell.y + 0.5) * r;
        if (cx * cx + cy * cy > 0.25) continue;
        ++cells;
        const CellEstimate e = offline_->Estimate(cell);
        if (std::isnan(e.traversability)) {
          ++unknown;
        } else if (std::isnan(worst) || e.traversability > worst) {
          worst = e.traversability;
        }
      }
    }
    EXPECT_EQ(check->poses[i].cell_count, static_cast<uint32_t>(cells));
    EXPECT_NEAR(check->poses[i].unknown_fraction, static_cast<float>(unknown) / cells, 1e-6);
    if (std::isnan(worst)) {
      EXPECT_TRUE(std::isnan(check->poses[i].worst_traversability));
    } else {
      EXPECT_FLOAT_EQ(check->poses[i].worst_traversability, worst);
    }
  }
  // A polygon footprint and default thresholds answer too; a far-away path is unknown: unsafe.
  PathQuery far;
  far.poses = {{5000, 5000, 0.3}};
  far.polygon = {{-0.4, -0.3}, {0.4, -0.3}, {0.4, 0.3}, {-0.4, 0.3}};
  RpcResult<PathCheck> unknown = fixture_->client().CheckPath(far);
  ASSERT_TRUE(unknown.ok()) << unknown.status().ToString();
  EXPECT_FALSE(unknown->safe);
  EXPECT_EQ(unknown->first_unsafe_index, 0);
  EXPECT_FLOAT_EQ(unknown->poses[0].unknown_fraction, 1.0f);
  EXPECT_GT(unknown->poses[0].cell_count, 30u);
}

// Issue 29: a planner sends waypoints and means the path between them. Two poses that are
// safe on their own, joined by a straight segment over the unknown ground under the sensor at
// (0, 0), are an unsafe path.
TEST_F(ServedMapTest, PathCheckSeesTheGroundBetweenPoses) {
  PathQuery q;
  q.poses = {{-8, -2, 0}, {8, 2, 0}};
  q.radius = 0.3;
  // The premise, on the offline map: each pose alone is safe, the midpoint is not.
  const MapParams& params = offline_->params();
  const PathThresholds thresholds{params.trav_threshold, params.variance_threshold, 0.0};
  Footprint disk;
  disk.radius = q.radius;
  auto judge = [&](const Pose2& p) {
    std::vector<CellEstimate> cells;
    for (CellIndex c : FootprintCells(offline_->geometry(), disk, p)) {
      cells.push_back(offline_->Estimate(c));
    }
    return JudgeFootprint(cells, thresholds);
  };
  ASSERT_TRUE(judge(q.poses[0]).safe);
  ASSERT_TRUE(judge(q.poses[1]).safe);
  ASSERT_FALSE(judge({0, 0, 0}).safe);

  RpcResult<PathCheck> check = fixture_->client().CheckPath(q);
  ASSERT_TRUE(check.ok()) << check.status().ToString();
  EXPECT_TRUE(check->poses[0].safe);
  EXPECT_TRUE(check->poses[1].safe);
  EXPECT_FALSE(check->safe);
  EXPECT_EQ(check->first_unsafe_index, 0);  // the trouble begins after pose 0
  ASSERT_EQ(check->segments.size(), 1u);
  EXPECT_FALSE(check->segments[0].safe);
  EXPECT_EQ(check->segments[0].placement_count, 164u);  // 16.49 m at 0.1 m: 165 steps
  // The first unsafe point: on segment 0, on the line, and the first placement of the rule
  // (docs/semantics.md, "Path checks") that the offline map judges unsafe.
  ASSERT_TRUE(check->first_unsafe.has_value());
  const PlacementCheck& first = *check->first_unsafe;
  EXPECT_EQ(first.where.segment, 0u);
  EXPECT_GT(first.where.t, 0.0);
  EXPECT_LT(first.where.t, 1.0);
  EXPECT_NEAR(first.where.pose.y, first.where.pose.x / 4, 1e-9);  // on y = x / 4
  EXPECT_FALSE(first.check.safe);
  const int n = 165;
  int want = -1;
  for (int k = 1; k < n && want < 0; ++k) {
    const double t = static_cast<double>(k) / n;
    if (!judge({-8 + t * 16, -2 + t * 4, 0}).safe) want = k;
  }
  ASSERT_GT(want, 0);
  EXPECT_DOUBLE_EQ(first.where.t, static_cast<double>(want) / n);
  const PoseCheck offline = judge(first.where.pose);
  EXPECT_EQ(first.check.cell_count, offline.cell_count);
  EXPECT_FLOAT_EQ(first.check.unknown_fraction, offline.unknown_fraction);
  // The midpoint as a pose of its own is unsafe, and the path is unsafe before it already.
  PathQuery with_mid = q;
  with_mid.poses.insert(with_mid.poses.begin() + 1, {0, 0, 0});
  RpcResult<PathCheck> mid = fixture_->client().CheckPath(with_mid);
  ASSERT_TRUE(mid.ok()) << mid.status().ToString();
  EXPECT_FALSE(mid->safe);
  EXPECT_FALSE(mid->poses[1].safe);
  EXPECT_EQ(mid->first_unsafe_index, 0);
  // Sampled afresh (83 steps to the midpoint), the first unsafe point is within a step.
  EXPECT_EQ(mid->first_unsafe->where.segment, 0u);
  EXPECT_NEAR(mid->first_unsafe->where.pose.x, first.where.pose.x, 0.1);
}

}  // namespace
}  // namespace bgkmap::testing

namespace bgkmap::testing {
namespace {

// Nice values of this process's threads (field 19 of /proc/self/task/TID/stat).
std::vector<int> ThreadNiceValues() {
  std::vector<int> out;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream in(entry.path() / "stat");
    std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // The command name may hold spaces: fields are counted after its closing parenthesis.
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));
    std::string field;
    for (int i = 3; i <= 19 && fields >> field; ++i) {
      if (i == 19) out.push_back(std::stoi(field));
    }
  }
  return out;
}

TEST(WorkerPriorityTest, WorkerThreadsRunAtTheConfiguredNice) {
  ServerConfig config = TestConfig();
  config.worker_nice = 7;
  const auto before = ThreadNiceValues();
  const auto count7 = [](const std::vector<int>& v) { return std::count(v.begin(), v.end(), 7); };
  ServerFixture fixture(config);
  EXPECT_EQ(count7(ThreadNiceValues()) - count7(before), config.worker_threads);
  EXPECT_TRUE(fixture.client().Info().ok());  // queries still answered
}

// The CPUs each of this process's threads may run on, one entry per thread.
std::vector<std::vector<int>> ThreadCpus() {
  std::vector<std::vector<int>> out;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    cpu_set_t set;
    CPU_ZERO(&set);
    const pid_t tid = static_cast<pid_t>(std::stol(entry.path().filename().string()));
    if (sched_getaffinity(tid, sizeof(set), &set) != 0) continue;  // the thread ended
    std::vector<int> cpus;
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &set)) cpus.push_back(c);
    }
    out.push_back(std::move(cpus));
  }
  return out;
}

TEST(WorkerPinningTest, WorkersArePinnedToTheConfiguredCpusAndOthersAreNot) {
  cpu_set_t allowed;
  ASSERT_EQ(sched_getaffinity(0, sizeof(allowed), &allowed), 0);
  std::vector<int> cpus;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &allowed)) cpus.push_back(c);
  }
  if (cpus.size() < 2) GTEST_SKIP() << "needs two CPUs to tell a pinned thread from another";
  ServerConfig config = TestConfig();
  config.worker_threads = 3;
  config.worker_cpus = {cpus[1], cpus[0]};  // worker i on worker_cpus[i % 2]
  const auto count_on = [](const std::vector<std::vector<int>>& threads, int cpu) {
    return std::count(threads.begin(), threads.end(), std::vector<int>{cpu});
  };
  const auto before = ThreadCpus();
  ServerFixture fixture(config);
  const auto after = ThreadCpus();
  EXPECT_EQ(count_on(after, cpus[1]) - count_on(before, cpus[1]), 2);  // workers 0 and 2
  EXPECT_EQ(count_on(after, cpus[0]) - count_on(before, cpus[0]), 1);  // worker 1
  // The query threads and gRPC's keep every CPU.
  EXPECT_GT(std::count(after.begin(), after.end(), cpus),
            std::count(before.begin(), before.end(), cpus));
  std::vector<ScanData> scans;
  for (const OwnedScan& s : StreetScans()) scans.push_back(s.Data());
  RpcResult<std::vector<ScanAck>> acks = fixture.client().IngestAll(scans);
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();  // pinned workers integrate
  EXPECT_TRUE(fixture.client().Info().ok());
}

TEST(WorkerPinningTest, ACpuTheProcessMayNotRunOnIsRefusedAtStart) {
  cpu_set_t allowed;
  ASSERT_EQ(sched_getaffinity(0, sizeof(allowed), &allowed), 0);
  int outside = -1;
  for (int c = CPU_SETSIZE - 1; c >= 0 && outside < 0; --c) {
    if (!CPU_ISSET(c, &allowed)) outside = c;
  }
  if (outside < 0) GTEST_SKIP() << "this process may run on every CPU number";
  ServerConfig config = TestConfig();
  config.worker_cpus = {outside};
  Result<std::unique_ptr<MapServer>> start = MapServer::Start(config);
  ASSERT_FALSE(start.ok());
  EXPECT_EQ(start.status().message().rfind("server.worker_cpus: CPU " + std::to_string(outside) +
                                               " is not one this process may run on",
                                           0),
            0u)
      << start.status().ToString();
}

}  // namespace
}  // namespace bgkmap::testing
