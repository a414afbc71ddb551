// Watch delivers every changed tile (coalesced per tile) and a slow watcher never holds back
// ingestion.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

// Collects updates; remembers the newest version seen per tile and the latest content.
class Collector {
 public:
  explicit Collector(std::chrono::milliseconds delay = {}) : delay_(delay) {}
  void operator()(const TileUpdate& u) {
    if (delay_.count() > 0) std::this_thread::sleep_for(delay_);
    std::lock_guard lock(mu_);
    ++count_;
    uint64_t& v = newest_[u.key];
    v = std::max(v, u.tile_version);
    latest_[u.key] = u.raster;
    cv_.notify_all();
  }
  // Waits until every tile of `want` has been seen at its version or newer.
  bool WaitFor(const std::map<TileKey, uint64_t>& want, std::chrono::seconds timeout) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return Covers(want); });
  }
  bool CoversNow(const std::map<TileKey, uint64_t>& want) {
    std::lock_guard lock(mu_);
    return Covers(want);
  }
  size_t count() {
    std::lock_guard lock(mu_);
    return count_;
  }
  std::map<TileKey, uint64_t> newest() {
    std::lock_guard lock(mu_);
    return newest_;
  }
  std::map<TileKey, Raster> latest() {
    std::lock_guard lock(mu_);
    return latest_;
  }

 private:
  bool Covers(const std::map<TileKey, uint64_t>& want) const {
    for (const auto& [k, v] : want) {
      auto it = newest_.find(k);
      if (it == newest_.end() || it->second < v) return false;
    }
    return true;
  }
  std::chrono::milliseconds delay_;
  std::mutex mu_;
  std::condition_variable cv_;
  size_t count_ = 0;
  std::map<TileKey, uint64_t> newest_;
  std::map<TileKey, Raster> latest_;
};

// Tile -> version of its last change, from the acks.
std::map<TileKey, uint64_t> LastChanges(const std::vector<ScanAck>& acks, size_t* changes) {
  std::map<TileKey, uint64_t> out;
  *changes = 0;
  for (const ScanAck& a : acks) {
    for (TileKey k : a.changed_tiles) {
      out[k] = std::max(out[k], a.map_version);
      ++*changes;
    }
  }
  return out;
}

std::vector<ScanAck> Ingest(Client& client, const std::vector<OwnedScan>& scans) {
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
  EXPECT_TRUE(acks.ok()) << acks.status().ToString();
  return acks.ok() ? *acks : std::vector<ScanAck>{};
}

// A watcher and the tiles it watches.
struct Watched {
  Collector* collector;
  TileKey min, max;
};

// Readiness of Watch subscriptions without a fixed sleep: sends small probe scans (robot
// "probe", on the ground around (2.5, 2.5) m, so in tile (0, 0)) until every watcher has seen
// the tiles the latest probe changed. A subscription that registers after a probe misses it, so
// the probes repeat, each waited for briefly, up to a generous deadline. Returns the collectors'
// update counts once they are ready, for tests that count the updates that follow.
std::vector<size_t> AwaitSubscribed(Client& client, const std::vector<Watched>& watchers) {
  std::vector<Point3f> points;
  for (int i = 0; i < 400; ++i) {  // a disc of ground 1.5 m below the sensor, r in [1.2, 2] m
    const double a = 0.1 * i, r = 1.2 + 0.002 * i;
    points.push_back(
        {static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)), -1.5f});
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (uint64_t sequence = 1;; ++sequence) {
    ScanData probe;
    probe.robot_id = "probe";
    probe.sequence = sequence;
    probe.pose.tx = probe.pose.ty = 2.5;
    probe.pose.tz = 1.5;
    probe.points = points;
    RpcResult<ScanAck> ack = client.Insert(probe);
    EXPECT_TRUE(ack.ok()) << ack.status().ToString();
    if (!ack.ok()) return {};
    bool seen = true;
    for (const Watched& w : watchers) {
      std::map<TileKey, uint64_t> want;
      for (TileKey k : ack->changed_tiles) {
        if (k.x >= w.min.x && k.x <= w.max.x && k.y >= w.min.y && k.y <= w.max.y) {
          want[k] = ack->map_version;
        }
      }
      EXPECT_FALSE(want.empty()) << "the probe changes no watched tile";
      seen = seen && !want.empty() && w.collector->WaitFor(want, std::chrono::seconds(2));
    }
    if (seen) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ADD_FAILURE() << "watch subscriptions not live after " << sequence << " probes";
      break;
    }
  }
  std::vector<size_t> counts;
  for (const Watched& w : watchers) counts.push_back(w.collector->count());
  return counts;
}

TEST(WatchTest, DeliversEveryChangedTileWithItsLatestContent) {
  ServerFixture fixture;
  Collector all;
  auto watch = fixture.client().Watch({{-500, -500, 500, 500}, {}, false},
                                      [&](const TileUpdate& u) { all(u); });
  Collector near;
  auto small = fixture.client().Watch({{0, 0, 5, 5}, {Layer::kElevation}, false},
                                      [&](const TileUpdate& u) { near(u); });
  const std::vector<size_t> ready =
      AwaitSubscribed(fixture.client(), {{&all, {-50, -50}, {50, 50}}, {&near, {0, 0}, {0, 0}}});
  ASSERT_EQ(ready.size(), 2u);

  const std::vector<ScanAck> acks = Ingest(fixture.client(), SubScans("w", 3, 6));
  size_t changes = 0;
  const std::map<TileKey, uint64_t> want = LastChanges(acks, &changes);
  ASSERT_FALSE(want.empty());
  ASSERT_TRUE(all.WaitFor(want, std::chrono::seconds(60)));
  // Coalesced, never more than one update per change (the probes' updates are all in `ready`).
  EXPECT_LE(all.count() - ready[0], changes);

  // The last update of each tile holds the tile's final content.
  std::unique_ptr<TerrainMap> map = fixture.server().SnapshotMap();
  std::vector<Layer> layers;
  for (int i = 0; i < kLayerCount; ++i) layers.push_back(static_cast<Layer>(i));
  for (const auto& [key, raster] : all.latest()) {
    const Raster expect = ExtractRaster(*map, map->geometry().TileBox(key), layers, 1);
    EXPECT_TRUE(RastersMatch(raster, expect, 0.0)) << key.x << "," << key.y;
  }
  // The small watcher saw only its tile(s) (cells 0..49 -> tile 0,0), with one layer.
  // The scans start at the origin, so tile (0, 0) changes and the small watcher has something to
  // see: without that, the two loops below would pass on no update at all.
  ASSERT_TRUE(want.count({0, 0}));
  const std::map<TileKey, uint64_t> want_near = {{{0, 0}, want.at({0, 0})}};
  ASSERT_TRUE(near.WaitFor(want_near, std::chrono::seconds(30)));
  ASSERT_FALSE(near.newest().empty());
  for (const auto& [key, _] : near.newest()) EXPECT_EQ(key, (TileKey{0, 0}));
  ASSERT_FALSE(near.latest().empty());
  for (const auto& [key, raster] : near.latest()) EXPECT_EQ(raster.layers.size(), 1u);

  watch->Cancel();
  EXPECT_EQ(watch->Wait().code(), RpcCode::kCancelled);
}

TEST(WatchTest, DeliversClearedTilesToo) {
  ServerFixture fixture;
  Ingest(fixture.client(), SubScans("w", 8, 1));
  Collector c;
  auto watch = fixture.client().Watch({{-500, -500, 500, 500}, {Layer::kElevation}, false},
                                      [&](const TileUpdate& u) { c(u); });
  AwaitSubscribed(fixture.client(), {{&c, {-50, -50}, {50, 50}}});
  RpcResult<ClearResult> clear = fixture.client().ClearRegion({-20, -20, 20, 20});
  ASSERT_TRUE(clear.ok());
  ASSERT_FALSE(clear->changed_tiles.empty());
  std::map<TileKey, uint64_t> want;
  for (TileKey k : clear->changed_tiles) want[k] = clear->map_version;
  ASSERT_TRUE(c.WaitFor(want, std::chrono::seconds(60)));
  // Tiles wholly inside the box are empty now.
  int inside = 0;
  for (const auto& [key, raster] : c.latest()) {
    if (key.x >= -2 && key.x <= 2 && key.y >= -2 && key.y <= 2) {
      ++inside;
      ASSERT_FALSE(raster.data[0].empty());
      for (float v : raster.data[0]) ASSERT_TRUE(std::isnan(v));
    }
  }
  EXPECT_GT(inside, 0);  // the check above ran on some cleared tile
}

TEST(WatchTest, InitialSnapshotSendsExistingTiles) {
  ServerFixture fixture;
  const std::vector<ScanAck> acks = Ingest(fixture.client(), SubScans("w", 8, 1));
  size_t changes = 0;
  const std::map<TileKey, uint64_t> want = LastChanges(acks, &changes);
  Collector c;
  auto watch = fixture.client().Watch({{-500, -500, 500, 500}, {}, true},
                                      [&](const TileUpdate& u) { c(u); });
  EXPECT_TRUE(c.WaitFor(want, std::chrono::seconds(60)));
}

TEST(WatchTest, SlowWatcherDoesNotHoldBackIngest) {
  ServerFixture fixture;
  Collector slow(std::chrono::milliseconds(60));
  auto watch = fixture.client().Watch({{-20, -20, 20, 20}, {}, false},
                                      [&](const TileUpdate& u) { slow(u); });
  const std::vector<size_t> ready = AwaitSubscribed(fixture.client(), {{&slow, {-4, -4}, {3, 3}}});
  ASSERT_EQ(ready.size(), 1u);
  const std::vector<ScanAck> acks = Ingest(fixture.client(), SubScans("w", 4, 12));
  size_t changes = 0;
  std::map<TileKey, uint64_t> want = LastChanges(acks, &changes);
  std::erase_if(want, [](const auto& kv) {  // only the watched tiles: x, y in [-4, 3]
    return kv.first.x < -4 || kv.first.x > 3 || kv.first.y < -4 || kv.first.y > 3;
  });
  // Ingestion finished long before the watcher could take one update per change.
  EXPECT_FALSE(slow.CoversNow(want));
  // It still catches up, with far fewer messages than changes.
  ASSERT_TRUE(slow.WaitFor(want, std::chrono::seconds(120)));
  EXPECT_LT(slow.count() - ready[0], changes);
}

}  // namespace
}  // namespace bgkmap::testing
