// Corrections in the store: retained checkpoints (bases), their tile history, and re-integration
// of revised scans equal, bit for bit, the map rebuilt from scratch with the revised scans.
#include "bgkmap/storage/reintegration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::MakeRawScan;
using testing::NewMap;
using testing::SmallParams;
using testing::StatisticsIdentical;
using testing::TempDir;
using testing::Terrain;

// Odometry that drifts: 2 cm and 0.2 degrees of yaw more per scan.
Pose Drifted(const Pose& truth, int index) {
  Pose p = truth;
  const double yaw = 0.0035 * index;
  p.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation += Eigen::Vector3d(0.02 * index, -0.015 * index, 0.01 * index);
  return p;
}

// Prepared as the server does: stamped with the scan's map time.
std::shared_ptr<const PreparedScan> Prepare(const MapParams& params, const RawScan& source,
                                            int64_t stamp_ns) {
  Result<PreparedScan> scan = PrepareScan(params, source.points, source.pose, source.frame_is_map);
  EXPECT_TRUE(scan.ok()) << scan.status().ToString();
  scan->stamp_ns = stamp_ns;
  return std::make_shared<const PreparedScan>(std::move(scan).value());
}

StoreOptions Retaining(uint64_t max_bytes = uint64_t{1} << 30) {
  StoreOptions o;
  o.durability = Durability::kPeriodic;
  o.retention.max_bytes = max_bytes;
  return o;
}

// Two robots, interleaved (version v is robot v % 2, scan v / 2); robot 0 on drifting odometry.
// The live map, the store (checkpoint every 7 versions) and the raw scans as sent.
struct Drive {
  MapParams params = SmallParams();
  TempDir dir;
  std::unique_ptr<TileStore> store;
  std::unique_ptr<TerrainMap> map = NewMap(params);
  std::map<uint64_t, LogRecord> records;  // as logged

  // With `half_life_s` > 0 the map forgets, and robot 1's stamps run 3.5 s behind robot 0's.
  explicit Drive(int versions, StoreOptions options = Retaining(), double half_life_s = 0,
                 Method method = Method::kBgkPlus) {
    params.half_life_s = half_life_s;
    params.method = method;
    map = NewMap(params);
    store = std::move(TileStore::Open(dir.path(), options, params)).value();
    testing::Checkpointer checkpointer;
    for (int v = 1; v <= versions; ++v) {
      const int robot = v % 2, index = v / 2;
      auto source = std::make_shared<RawScan>(MakeRawScan(robot, index));
      if (robot == 0) source->pose = Drifted(source->pose, index);
      const int64_t stamp =
          1'000'000'000LL * v - (half_life_s > 0 && robot == 1 ? 3'500'000'000LL : 0);
      LogRecord record = LogRecord::Scan(v, "robot-" + std::to_string(robot), index + 1,
                                         Prepare(params, *source, stamp), stamp);
      record.raw_scan = source;
      EXPECT_TRUE(store->log().Append(record).ok());
      checkpointer.MarkDirty(Apply(*map, *record.scan, v));
      records.emplace(v, std::move(record));
      if (v % 7 == 0) {
        EXPECT_TRUE(checkpointer.Checkpoint(*store, *map).ok());
      }
    }
  }

  // The map built from scratch from the logged scans, with `revised` in place of some (null:
  // removed).
  std::unique_ptr<TerrainMap> Rebuilt(
      const std::map<uint64_t, std::shared_ptr<const PreparedScan>>& revised) const {
    auto out = NewMap(params);
    for (const auto& [v, record] : records) {
      auto r = revised.find(v);
      if (r != revised.end() && r->second == nullptr) continue;
      Apply(*out, r != revised.end() ? *r->second : *record.scan, v);
    }
    return out;
  }

  uint64_t BaseBelow(uint64_t version) const {
    uint64_t base = 0;
    for (uint64_t b : store->Bases()) {
      if (b < version) base = b;
    }
    return base;
  }
};

TEST(TileHistory, LoadTilesAtReturnsEachTileAsItWasAtTheRetainedCheckpoint) {
  Drive drive(14);  // checkpoints at 7 and 14
  EXPECT_EQ(drive.store->Bases(), (std::vector<uint64_t>{0, 7, 14}));
  const auto at7 = drive.Rebuilt({});
  // Replay only up to 7 for the reference.
  auto reference = NewMap(drive.params);
  for (uint64_t v = 1; v <= 7; ++v) Apply(*reference, *drive.records.at(v).scan, v);
  std::vector<TileKey> keys;
  drive.map->ForEachTile([&](TileKey k, const Tile&) { keys.push_back(k); });
  auto tiles = drive.store->LoadTilesAt(7, keys);
  ASSERT_TRUE(tiles.ok()) << tiles.status().ToString();
  auto loaded = NewMap(drive.params);
  for (size_t i = 0; i < keys.size(); ++i) {
    if ((*tiles)[i]) loaded->SetTile(keys[i], *(*tiles)[i]);
  }
  EXPECT_TRUE(StatisticsIdentical(*reference, *loaded));
  // Version 0 is the empty map; a version that was never a checkpoint is refused.
  auto empty = drive.store->LoadTilesAt(0, keys);
  ASSERT_TRUE(empty.ok());
  for (const auto& t : *empty) EXPECT_EQ(t, nullptr);
  EXPECT_EQ(drive.store->LoadTilesAt(5, keys).status().code(), Status::Code::kInvalidArgument);
}

// Corrects robot 0's scans 10.. to their true poses, in the store and the live map; returns the
// revised training sets by version.
std::map<uint64_t, std::shared_ptr<const PreparedScan>> CorrectRobot0(Drive& drive, int from,
                                                                      uint64_t version) {
  std::map<uint64_t, std::shared_ptr<const PreparedScan>> revised;
  std::vector<LogRecord> rewritten;
  std::set<TileKey> seeds;
  for (const auto& [v, record] : drive.records) {
    if (v % 2 != 0 || static_cast<int>(v / 2) < from) continue;
    auto source = std::make_shared<RawScan>(MakeRawScan(0, static_cast<int>(v / 2)));
    revised[v] = Prepare(drive.params, *source, record.stamp_ns);  // a new pose, the same time
    const auto old = record.scan->ChangeableTiles();
    seeds.insert(old.begin(), old.end());
    LogRecord r = record;
    r.scan = revised[v];
    r.raw_scan = source;
    rewritten.push_back(std::move(r));
  }
  ReintegrationRequest request;
  request.base = drive.BaseBelow(revised.begin()->first);
  request.end = version;
  request.seed_tiles.assign(seeds.begin(), seeds.end());
  request.replacements = revised;
  auto result = Reintegrate(*drive.store, request);
  EXPECT_TRUE(result.ok()) << result.status().ToString();
  if (!result.ok()) return revised;
  EXPECT_GT(result->records_replayed, 0u);
  EXPECT_LE(result->records_replayed, result->records_in_history);
  InstallTiles(result->affected, result->tiles, version, *drive.map);
  std::vector<uint64_t> versions;
  for (const auto& [v, scan] : revised) versions.push_back(v);
  const LogRecord correction =
      LogRecord::Correction(version, "robot-0", request.base, request.seed_tiles, versions);
  EXPECT_TRUE(drive.store->ApplyCorrection(correction, rewritten, {}).ok());
  for (LogRecord& r : rewritten) drive.records[r.version] = std::move(r);
  return revised;
}

TEST(Reintegration, CorrectedMapEqualsTheMapBuiltFromScratchWithTheCorrectedPosesBitwise) {
  Drive drive(40);
  const auto drifted = drive.Rebuilt({});
  ASSERT_TRUE(StatisticsIdentical(*drifted, *drive.map));
  const auto revised = CorrectRobot0(drive, 10, 41);
  const auto truth = drive.Rebuilt({});  // the records now hold the corrected scans
  EXPECT_TRUE(StatisticsIdentical(*truth, *drive.map));
  // The correction changed something (it is not vacuous).
  EXPECT_FALSE(StatisticsIdentical(*drifted, *drive.map));

  // Recovery (checkpoint at 35, records 36..40 and the correction at 41) gives the same map.
  auto recovered = NewMap(drive.params);
  auto report = RecoverMap(*drive.store, *recovered);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->corrections_replayed, 1u);
  ASSERT_TRUE(LoadAllTiles(*drive.store, *recovered).ok());
  EXPECT_TRUE(StatisticsIdentical(*truth, *recovered));
  // The bases between the correction's base and itself are gone: their history predates it.
  for (uint64_t b : drive.store->Bases()) EXPECT_TRUE(b <= 14 || b >= 41) << b;
}

// Corrects robot 0 from version 10 (as version 41); the live map and the map recovered from
// the store then equal the map rebuilt from scratch with the corrected scans, bitwise.
void ExpectCorrectionAndRecoveryEqualTheRebuild(Drive& drive) {
  CorrectRobot0(drive, 10, 41);
  const auto truth = drive.Rebuilt({});
  EXPECT_TRUE(StatisticsIdentical(*truth, *drive.map));
  auto recovered = NewMap(drive.params);
  ASSERT_TRUE(RecoverMap(*drive.store, *recovered).ok());
  ASSERT_TRUE(LoadAllTiles(*drive.store, *recovered).ok());
  EXPECT_TRUE(StatisticsIdentical(*truth, *recovered));
}

// Forgetting (docs/semantics.md): the log's stamps are the scans' map times, so the rebuild and
// recovery age evidence exactly as the live map did, late scans of the other robot included.
// Mutation checked: the log decoder not putting the record's stamp on the scan fails it.
TEST(Reintegration, WithForgettingTheCorrectedMapIsStillTheRebuiltOneBitwise) {
  Drive drive(40, Retaining(), 3.0);
  ASSERT_TRUE(StatisticsIdentical(*drive.Rebuilt({}), *drive.map));
  ExpectCorrectionAndRecoveryEqualTheRebuild(drive);
  int stamped = 0;
  drive.map->ForEachTile([&](TileKey, const Tile& t) { stamped += t.stamp_ns() != 0 ? 1 : 0; });
  EXPECT_GT(stamped, 0);
}

// bgk-ll (plane moments in every tile, tile format 4): the correction, the tile history it
// starts from and recovery give the map rebuilt from scratch, bitwise. Found failing: a tile the
// correction emptied was installed as an empty tile without moments, and TerrainMap::SetTile
// left the old tile's moments behind.
TEST(Reintegration, WithBgkLlTheCorrectedMapIsStillTheRebuiltOneBitwise) {
  Drive drive(40, Retaining(), 0, Method::kBgkLocalLinear);
  ExpectCorrectionAndRecoveryEqualTheRebuild(drive);
  int planes = 0;
  drive.map->ForEachTile([&](TileKey, const Tile& t) { planes += t.has_plane() ? 1 : 0; });
  EXPECT_EQ(planes, static_cast<int>(drive.map->tile_count()));
}

TEST(Reintegration, ASecondCorrectionReachingFurtherBackStaysExact) {
  Drive drive(40);
  CorrectRobot0(drive, 16, 41);
  CorrectRobot0(drive, 4, 42);
  EXPECT_TRUE(StatisticsIdentical(*drive.Rebuilt({}), *drive.map));
}

TEST(Reintegration, RemovedScansLeaveTheMapWithoutThem) {
  Drive drive(30);
  std::map<uint64_t, std::shared_ptr<const PreparedScan>> removed;
  std::set<TileKey> seeds;
  for (uint64_t v = 13; v <= 30; v += 2) {  // robot 1, scans 6..15
    removed[v] = nullptr;
    const auto old = drive.records.at(v).scan->ChangeableTiles();
    seeds.insert(old.begin(), old.end());
  }
  ReintegrationRequest request;
  request.base = drive.BaseBelow(13);
  request.end = 31;
  request.seed_tiles.assign(seeds.begin(), seeds.end());
  request.replacements = removed;
  auto result = Reintegrate(*drive.store, request);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  InstallTiles(result->affected, result->tiles, 31, *drive.map);
  EXPECT_TRUE(StatisticsIdentical(*drive.Rebuilt(removed), *drive.map));
}

// The closure on tile sets alone (plan_only), with hand-made scans: a scan that only reads a
// corrected tile is affected; a scan whose output a replayed scan reads is replayed.
// (Mutations: dropping read_tiles from either pass fails this test.)
TEST(Reintegration, AffectedAndNeededTilesFollowReadsForwardAndBackward) {
  TempDir dir;
  auto store = std::move(TileStore::Open(dir.path(), Retaining(), SmallParams())).value();
  auto scan = [](std::vector<TileKey> write, std::vector<TileKey> read) {
    auto s = std::make_shared<PreparedScan>();
    s->write_tiles = std::move(write);
    s->read_tiles = std::move(read);
    return std::shared_ptr<const PreparedScan>(s);
  };
  const std::vector<std::shared_ptr<const PreparedScan>> scans = {
      scan({{0, 0}}, {{1, 0}}), scan({{1, 0}}, {{0, 0}}), scan({{2, 0}}, {{1, 0}}),
      scan({{9, 9}}, {})};
  for (size_t i = 0; i < scans.size(); ++i) {
    ASSERT_TRUE(store->log().Append(LogRecord::Scan(i + 1, "r", i + 1, scans[i])).ok());
  }
  ReintegrationRequest request;
  request.base = 0;
  request.end = 5;
  request.seed_tiles = {{1, 0}};
  request.replacements[2] = scans[1];
  request.plan_only = true;
  auto plan = Reintegrate(*store, request);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->affected, (std::vector<TileKey>{{1, 0}, {2, 0}}));
  EXPECT_EQ(plan->needed, (std::vector<TileKey>{{0, 0}, {1, 0}, {2, 0}}));
  EXPECT_EQ(plan->records_in_history, 4u);
  EXPECT_EQ(plan->records_replayed, 3u);
}

TEST(Reintegration, RefusesABaseThatIsNotRetainedAndAVersionThatIsNotAScan) {
  Drive drive(10);
  ReintegrationRequest request;
  request.base = 3;
  request.end = 11;
  EXPECT_EQ(Reintegrate(*drive.store, request).status().code(), Status::Code::kInvalidArgument);
  request.base = 7;
  request.replacements[2] = nullptr;  // below the base
  EXPECT_EQ(Reintegrate(*drive.store, request).status().code(), Status::Code::kInvalidArgument);
}

TEST(Retention, TheByteBoundDropsOldBasesWithTheirLogAndHistory) {
  // ~12 raw scans of 18 KB; the bound is RocksDB's estimate, so only its effect is asserted.
  Drive drive(42, Retaining(/*max_bytes=*/200'000));
  const std::vector<uint64_t> bases = drive.store->Bases();
  ASSERT_FALSE(bases.empty());
  EXPECT_GT(bases.front(), 0u);
  EXPECT_EQ(bases.back(), 42u);
  auto stats = drive.store->log().Stats(0);
  ASSERT_TRUE(stats.ok());
  if (stats->records > 0) {
    EXPECT_GT(stats->first_version, bases.front());
  }
  auto source = drive.store->log().LoadRawScan(bases.front());
  ASSERT_TRUE(source.ok());
  EXPECT_FALSE(source->has_value());
  // What an old base kept is gone with it.
  std::vector<TileKey> keys = {TileKey{0, 0}};
  EXPECT_EQ(drive.store->LoadTilesAt(0, keys).status().code(), Status::Code::kInvalidArgument);
}

// An import changes the map outside the log: no rebuild may start before it.
TEST(Retention, AChangeOutsideTheLogForgetsEarlierBases) {
  Drive drive(14);
  ASSERT_EQ(drive.store->Bases(), (std::vector<uint64_t>{0, 7, 14}));
  ASSERT_TRUE(drive.store->Checkpoint(15, {}, /*forget_earlier_bases=*/true).ok());
  EXPECT_EQ(drive.store->Bases(), (std::vector<uint64_t>{15}));
  auto stats = drive.store->log().Stats(0);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->records, 0u);
}

TEST(Retention, WithoutItTheLogEndsAtTheCheckpointAndNoScanIsKept) {
  Drive drive(14, StoreOptions{});
  EXPECT_TRUE(drive.store->Bases().empty());
  auto stats = drive.store->log().Stats(0);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->records, 0u);
  auto source = drive.store->log().LoadRawScan(14);
  ASSERT_TRUE(source.ok());
  EXPECT_FALSE(source->has_value());
}

}  // namespace
}  // namespace bgkmap::storage
