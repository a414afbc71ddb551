// Region deltas (issue 27, docs/server.md "Region deltas"): a QueryRegion with since_version
// answers the changed tiles of the region (at stride 1 after scans, their changed blocks only),
// bit for bit a full query's pixels there, with
// tombstones for tiles a clear emptied; a copy kept by deltas equals a fresh full query after
// scans, clears, imports and pose corrections; a since_version the server cannot answer exactly
// gets the whole region, flagged.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cstring>
#include <set>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

const MetricBox kRegion{-30, -25, 35, 30};

// Bit for bit, NaNs included.
::testing::AssertionResult SameBits(const Raster& a, const Raster& b) {
  if (a.box.min != b.box.min || a.box.max != b.box.max || a.rows != b.rows || a.cols != b.cols ||
      a.layers != b.layers || a.data.size() != b.data.size()) {
    return ::testing::AssertionFailure() << "different geometry or layers";
  }
  for (size_t l = 0; l < a.data.size(); ++l) {
    if (a.data[l].size() != b.data[l].size() ||
        std::memcmp(a.data[l].data(), b.data[l].data(), a.data[l].size() * sizeof(float)) != 0) {
      return ::testing::AssertionFailure() << "layer " << l << " differs";
    }
  }
  return ::testing::AssertionSuccess();
}

// A copy of the region kept current by deltas, as a planner would keep one.
struct Mirror {
  Client& client;
  RegionQuery query;
  Raster copy;
  uint64_t version = 0, history = 0;
  RegionDelta last;

  Mirror(Client& c, RegionQuery q) : client(c), query(std::move(q)) {
    RpcResult<Raster> full = client.QueryRegion(query, &version, &history);
    EXPECT_TRUE(full.ok()) << full.status().ToString();
    copy = *full;
  }
  void Refresh() {
    RpcResult<RegionDelta> d = client.QueryRegionSince(query, version, history);
    ASSERT_TRUE(d.ok()) << d.status().ToString();
    ASSERT_TRUE(ApplyDelta(*d, &copy).ok());
    version = d->map_version;
    history = d->history_id;
    last = std::move(*d);
  }
  ::testing::AssertionResult EqualsAFreshQuery() {
    RpcResult<Raster> fresh = client.QueryRegion(query);
    if (!fresh.ok()) return ::testing::AssertionFailure() << fresh.status().ToString();
    return SameBits(copy, *fresh);
  }
};

void Send(Client& client, const std::vector<OwnedScan>& scans, size_t from, size_t to,
          std::set<TileKey>* changed = nullptr) {
  std::vector<ScanData> data;
  for (size_t i = from; i < to; ++i) data.push_back(scans[i].Data());
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
  for (const ScanAck& a : *acks) {
    ASSERT_EQ(a.status, AckStatus::kApplied) << a.error.ToString();
    if (changed != nullptr) changed->insert(a.changed_tiles.begin(), a.changed_tiles.end());
  }
}

TEST(RegionDelta, AfterOneScanItHoldsTheChangedTilesOfAFullQueryBitForBit) {
  ServerFixture fixture;
  const std::vector<OwnedScan> scans = SubScans("d", 4);
  Send(fixture.client(), scans, 0, 6);
  for (int stride : {1, 3}) {  // 3 does not divide the tile size: blocks straddle tiles
    const RegionQuery query{kRegion, {}, stride};
    Mirror mirror(fixture.client(), query);
    std::set<TileKey> changed;
    Send(fixture.client(), scans, 6 + stride, 7 + stride, &changed);
    mirror.Refresh();
    const RegionDelta& d = mirror.last;
    EXPECT_FALSE(d.full) << d.resync_reason;
    std::set<TileKey> sent;
    int64_t pixels_sent = 0;
    for (const RegionPatch& p : d.patches) {
      sent.insert(p.key);
      pixels_sent += p.rows * p.cols;
    }
    std::set<TileKey> expected;
    const GridGeometry g(0.1, 64);
    for (TileKey k : changed) {
      if (!TilePatchCells(g, d.raster.box, stride, k).empty()) expected.insert(k);
    }
    // Every tile sent was changed (a tile the scan listed but did not write is not sent).
    EXPECT_TRUE(std::includes(expected.begin(), expected.end(), sent.begin(), sent.end()));
    EXPECT_FALSE(sent.empty());
    int64_t pixels_of_tiles = 0;
    for (TileKey k : sent) {
      const CellBox cells = TilePatchCells(g, d.raster.box, stride, k);
      pixels_of_tiles +=
          ((cells.width() + stride - 1) / stride) * ((cells.height() + stride - 1) / stride);
    }
    if (stride == 1) {
      // After scans, at stride 1: the changed blocks, not the whole tiles.
      EXPECT_LT(pixels_sent, pixels_of_tiles);
    } else {
      EXPECT_EQ(pixels_sent, pixels_of_tiles);  // other strides: whole tiles
    }
    // Each patch holds exactly the full answer's pixels. (A tombstone here is a block the scan
    // may have written and left unknown: its pixels must be unknown in the full answer.)
    RpcResult<Raster> full = fixture.client().QueryRegion(query);
    ASSERT_TRUE(full.ok());
    int tombstones = 0;
    for (const RegionPatch& p : d.patches) {
      tombstones += p.tombstone;
      for (size_t l = 0; l < full->layers.size(); ++l) {
        const float unknown = UnknownValue(full->layers[l]);
        for (int64_t r = 0; r < p.rows; ++r) {
          const float* want = full->data[l].data() + (p.row_start + r) * full->cols + p.col_start;
          if (p.tombstone) {
            for (int64_t c = 0; c < p.cols; ++c) {
              ASSERT_EQ(std::bit_cast<uint32_t>(want[c]), std::bit_cast<uint32_t>(unknown));
            }
            continue;
          }
          ASSERT_EQ(std::memcmp(want, p.values[l].data() + r * p.cols, p.cols * sizeof(float)), 0)
              << "tile " << p.key.x << "," << p.key.y << " layer " << l << " row " << r;
        }
      }
    }
    EXPECT_LT(tombstones, static_cast<int>(d.patches.size()));
    EXPECT_TRUE(mirror.EqualsAFreshQuery());
    // Nothing changed since: an empty delta.
    mirror.Refresh();
    EXPECT_FALSE(mirror.last.full);
    EXPECT_TRUE(mirror.last.patches.empty());
  }
}

TEST(RegionDelta, ACompressedAnswerIsTheSame) {
  ServerFixture fixture;
  const std::vector<OwnedScan> scans = SubScans("z", 2);
  Send(fixture.client(), scans, 0, 3);
  RegionQuery query{kRegion, {}, 1};
  uint64_t version = 0, history = 0;
  RpcResult<Raster> plain = fixture.client().QueryRegion(query, &version, &history);
  ASSERT_TRUE(plain.ok());
  query.compress = true;
  RpcResult<Raster> gzipped = fixture.client().QueryRegion(query);
  ASSERT_TRUE(gzipped.ok()) << gzipped.status().ToString();
  EXPECT_TRUE(SameBits(*plain, *gzipped));
  Send(fixture.client(), scans, 3, 4);
  RpcResult<RegionDelta> d = fixture.client().QueryRegionSince(query, version, history);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_FALSE(d->full);
  Raster copy = *plain;
  ASSERT_TRUE(ApplyDelta(*d, &copy).ok());
  query.compress = false;
  RpcResult<Raster> fresh = fixture.client().QueryRegion(query);
  ASSERT_TRUE(fresh.ok());
  EXPECT_TRUE(SameBits(copy, *fresh));
}

TEST(RegionDelta, ClearRegionSendsTombstones) {
  ServerFixture fixture;
  const std::vector<OwnedScan> scans = SubScans("d", 2);
  Send(fixture.client(), scans, 0, scans.size());
  Mirror mirror(fixture.client(), {kRegion, {}, 1});
  // Tiles (-1..0, -1..0) whole: 6.4 m tiles at 0.1 m.
  RpcResult<ClearResult> clear = fixture.client().ClearRegion({-6.4, -6.4, 6.4, 6.4});
  ASSERT_TRUE(clear.ok()) << clear.status().ToString();
  mirror.Refresh();
  std::set<TileKey> tombstones;
  for (const RegionPatch& p : mirror.last.patches) {
    if (p.tombstone) tombstones.insert(p.key);
    EXPECT_EQ(p.tombstone, p.values.empty());
  }
  EXPECT_EQ(tombstones, (std::set<TileKey>{{-1, -1}, {-1, 0}, {0, -1}, {0, 0}}));
  EXPECT_TRUE(mirror.EqualsAFreshQuery());
  // A partly cleared tile comes with its values.
  ASSERT_TRUE(fixture.client().ClearRegion({6.4, 0.5, 8, 3}).ok());
  mirror.Refresh();
  ASSERT_EQ(mirror.last.patches.size(), 1u);
  EXPECT_EQ(mirror.last.patches[0].key, (TileKey{1, 0}));
  EXPECT_FALSE(mirror.last.patches[0].tombstone);
  EXPECT_TRUE(mirror.EqualsAFreshQuery());
}

TEST(RegionDelta, AMirrorEqualsAFreshQueryAfterScansClearsImportsAndCorrections) {
  TempDir dir;
  ServerConfig config = TestConfig();
  config.storage.data_dir = dir.Sub("map");
  ServerFixture fixture(config);
  std::vector<OwnedScan> scans = SubScans("r", 6, 12);
  const std::vector<OwnedScan> truth = scans;
  for (OwnedScan& s : scans) {  // drifting odometry, corrected below
    Pose p = WirePose(s.pose);
    p.translation += Eigen::Vector3d(0.05, 0.03, 0.0) * static_cast<double>(s.sequence);
    s.pose = ScanPose::FromPose(p);
  }
  Send(fixture.client(), scans, 0, 4);
  Mirror mirror(fixture.client(), {kRegion, {Layer::kElevation, Layer::kState}, 2});
  Send(fixture.client(), scans, 4, 8);
  mirror.Refresh();
  EXPECT_FALSE(mirror.last.full);
  EXPECT_TRUE(mirror.EqualsAFreshQuery());

  // (a correction replays the log: before the import, which is not in it)
  std::vector<std::pair<uint64_t, ScanPose>> poses;
  for (const OwnedScan& s : truth) {
    if (s.sequence >= 3 && s.sequence <= 8) poses.emplace_back(s.sequence, s.pose);
  }
  RpcResult<CorrectionResult> corrected = fixture.client().CorrectPoses("r", poses);
  ASSERT_TRUE(corrected.ok()) << corrected.status().ToString();
  mirror.Refresh();
  EXPECT_FALSE(mirror.last.full);
  EXPECT_FALSE(mirror.last.patches.empty());
  EXPECT_TRUE(mirror.EqualsAFreshQuery());

  ASSERT_TRUE(fixture.client().ClearRegion({-3, -3, 9, 4}).ok());
  mirror.Refresh();
  EXPECT_TRUE(mirror.EqualsAFreshQuery());

  const std::string archive = dir.Sub("self.bgkmap");
  ASSERT_TRUE(fixture.client().ExportMap(MetricBox{0, 0, 20, 20}, archive).ok());
  RpcResult<ImportResult> imported = fixture.client().ImportMap(archive);
  ASSERT_TRUE(imported.ok()) << imported.status().ToString();
  mirror.Refresh();
  EXPECT_FALSE(mirror.last.full);
  EXPECT_FALSE(mirror.last.patches.empty());
  EXPECT_TRUE(mirror.EqualsAFreshQuery());

  Send(fixture.client(), scans, 8, 12);
  mirror.Refresh();
  EXPECT_TRUE(mirror.EqualsAFreshQuery());
}

TEST(RegionDelta, AVersionItCannotAnswerExactlyGetsTheWholeRegionFlagged) {
  TempDir dir;
  ServerConfig config = TestConfig();
  config.storage.data_dir = dir.Sub("map");
  const std::vector<OwnedScan> scans = SubScans("d", 2);
  const RegionQuery query{kRegion, {}, 1};
  uint64_t version = 0, history = 0;
  {
    ServerFixture fixture(config);
    Send(fixture.client(), scans, 0, 3);
    ASSERT_TRUE(fixture.client().QueryRegion(query, &version, &history).ok());
    EXPECT_NE(history, 0u);
    // Ahead of the map, or of another history: not this map's version.
    RpcResult<RegionDelta> ahead = fixture.client().QueryRegionSince(query, version + 5);
    ASSERT_TRUE(ahead.ok());
    EXPECT_TRUE(ahead->full);
    EXPECT_NE(ahead->resync_reason.find("ahead"), std::string::npos) << ahead->resync_reason;
    RpcResult<RegionDelta> other = fixture.client().QueryRegionSince(query, version, history + 1);
    ASSERT_TRUE(other.ok());
    EXPECT_TRUE(other->full);
  }
  // Restarted on its store: the per-tile record starts over at the recovered version.
  ServerFixture restarted(config);
  RpcResult<Raster> now = restarted.client().QueryRegion(query);
  ASSERT_TRUE(now.ok());
  RpcResult<RegionDelta> old_history = restarted.client().QueryRegionSince(query, version, history);
  ASSERT_TRUE(old_history.ok());
  EXPECT_TRUE(old_history->full);
  EXPECT_TRUE(SameBits(old_history->raster, *now));
  RpcResult<RegionDelta> older = restarted.client().QueryRegionSince(query, version - 1);
  ASSERT_TRUE(older.ok());
  EXPECT_TRUE(older->full);
  EXPECT_NE(older->resync_reason.find("older"), std::string::npos) << older->resync_reason;
  RpcResult<RegionDelta> same = restarted.client().QueryRegionSince(query, version);
  ASSERT_TRUE(same.ok());
  EXPECT_FALSE(same->full) << same->resync_reason;  // the recovered map is the map at `version`
  EXPECT_TRUE(same->patches.empty());
}

}  // namespace
}  // namespace bgkmap::testing
