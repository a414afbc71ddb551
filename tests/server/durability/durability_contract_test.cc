// The Durability contract (durability/durability.h), run against every implementation: the
// store (StoreDurability on RocksDB in a temporary directory) and a map in memory
// (MemoryDurability). What one promises the served map, the other must promise too, except what
// the contract ties to persists() (stored tiles, the store's status).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/tile_codec.h"
#include "durability/memory_durability.h"
#include "durability/store_durability.h"
#include "test_support.h"

namespace bgkmap {
namespace {

using testing::TempDir;

struct MemoryKind {
  static Result<std::unique_ptr<Durability>> Open(const std::string&, const MapParams&,
                                                  const Georeference& georeference, TerrainMap&) {
    return std::unique_ptr<Durability>(new MemoryDurability(georeference));
  }
};

struct StoreKind {
  static Result<std::unique_ptr<Durability>> Open(const std::string& dir, const MapParams& params,
                                                  const Georeference& georeference,
                                                  TerrainMap& map) {
    StorageConfig config;
    config.data_dir = dir;
    config.min_free_space_mb = 0;  // whatever the machine's disk holds
    config.retention_mb = 0;       // no scans kept for corrections, as a map in memory
    Result<std::unique_ptr<StoreDurability>> opened =
        StoreDurability::Open(config, params, georeference, map);
    if (!opened.ok()) return opened.status();
    return std::unique_ptr<Durability>(std::move(opened).value());
  }
};

// The tiles in memory, as the served map's table hands them to the durability at a barrier.
class MapCopies final : public ResidentTiles {
 public:
  explicit MapCopies(const TerrainMap& map) : map_(map) {}
  std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const override {
    std::vector<std::unique_ptr<Tile>> out;
    for (TileKey k : keys) {
      const Tile* t = map_.FindTile(k);
      out.push_back(t != nullptr ? std::make_unique<Tile>(*t) : nullptr);
    }
    return out;
  }
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const override {
    std::vector<TileKey> out;
    map_.ForEachTile([&](TileKey k, const Tile&) {
      if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) out.push_back(k);
    });
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  const TerrainMap& map_;
};

std::shared_ptr<const PreparedScan> Ground(const MapParams& params, float cx) {
  std::vector<Point3f> points;
  for (float x = -4; x <= 4; x += 0.1f) {
    for (float y = -4; y <= 4; y += 0.1f) points.push_back({cx + x, y, -1.0f});
  }
  Result<PreparedScan> p = PrepareScan(params, points, Pose{}, /*frame_is_map=*/true);
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  return std::make_shared<PreparedScan>(std::move(p).value());
}

template <typename Kind>
class DurabilityContract : public ::testing::Test {
 protected:
  DurabilityContract()
      : dir_("bgkmap_durability"), map_(TerrainMap::Create(params_).value()), copies_(*map_) {
    Result<std::unique_ptr<Durability>> opened =
        Kind::Open(dir_.Sub("store"), params_, Georeference{}, *map_);
    EXPECT_TRUE(opened.ok()) << opened.status().ToString();
    if (opened.ok()) durability_ = std::move(opened).value();
  }

  // Integrates `scan` into the map in memory as version `version` (journaled first).
  void Apply(uint64_t version, std::shared_ptr<const PreparedScan> scan, uint64_t sequence) {
    static const std::string kRobot = "r";  // (assigning "r" trips GCC 12's -Wrestrict)
    ChangeRecord change;
    change.version = version;
    change.scan = scan;
    change.robot_id = kRobot;
    change.sequence = sequence;
    ASSERT_TRUE(durability_->Record(change).ok());
    const TileWindow window = map_->MakeWindow(*scan);
    map_->Integrate(*scan, window, version);
  }

  // Checkpoints every tile in memory at `version`.
  Status CheckpointAll(uint64_t version) {
    std::vector<TileKey> keys = copies_.ListTiles({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX});
    std::vector<std::unique_ptr<Tile>> tiles = copies_.CopyTiles(keys);
    return durability_->WriteCheckpoint(version, keys, tiles);
  }

  const MapParams params_;
  TempDir dir_;
  std::unique_ptr<TerrainMap> map_;
  MapCopies copies_;
  std::unique_ptr<Durability> durability_;
};

using Kinds = ::testing::Types<MemoryKind, StoreKind>;
class KindNames {
 public:
  template <typename T>
  static std::string GetName(int) {
    return std::is_same_v<T, MemoryKind> ? "Memory" : "Store";
  }
};
TYPED_TEST_SUITE(DurabilityContract, Kinds, KindNames);

TYPED_TEST(DurabilityContract, AFreshMapRecoversNothingAndFindsNothingWrong) {
  Durability& d = *this->durability_;
  EXPECT_EQ(d.recovered_version(), 0u);
  EXPECT_TRUE(d.LoggedRobotSequences().empty());
  EXPECT_TRUE(d.CorruptTiles().empty());
  EXPECT_FALSE(d.write_failed());
  EXPECT_FALSE(d.writes_paused_for_space());
  EXPECT_TRUE(d.Resume().ok());
  EXPECT_TRUE(d.DeferredTiles().empty());
  std::atomic<bool> stop{false};
  const Durability::VerifyReport verified = d.VerifyStoredTiles(stop);
  EXPECT_EQ(verified.corrupt, 0u);
  EXPECT_EQ(verified.unreadable, 0u);
  EXPECT_EQ(d.store_status(false).has_value(), d.persists());
}

TYPED_TEST(DurabilityContract, ChangesAreJournaledInVersionOrder) {
  this->Apply(1, Ground(this->params_, 0), 1);
  this->Apply(2, Ground(this->params_, 3), 2);
  ChangeRecord clear;
  clear.version = 3;
  clear.clear_box = CellBox{{0, 0}, {5, 5}};
  EXPECT_TRUE(this->durability_->Record(clear).ok());
  EXPECT_TRUE(this->durability_->RetireRobot("never-seen").ok());
}

TYPED_TEST(DurabilityContract, ACheckpointIsReadBackBitwiseWhenTheMapPersists) {
  this->Apply(1, Ground(this->params_, 0), 1);
  ASSERT_TRUE(this->CheckpointAll(1).ok());
  Durability& d = *this->durability_;
  size_t seen = 0;
  this->map_->ForEachTile([&](TileKey k, const Tile& in_memory) {
    ++seen;
    EXPECT_EQ(d.IsStored(k), d.persists());
    Result<std::unique_ptr<Tile>> loaded = d.Load(k);
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(d.StoredSummary(k).has_value(), d.persists());
    if (!d.persists()) {
      EXPECT_EQ(*loaded, nullptr);
      return;
    }
    ASSERT_NE(*loaded, nullptr);
    EXPECT_EQ(storage::EncodeTile(**loaded), storage::EncodeTile(in_memory));
  });
  EXPECT_GT(seen, 0u);
  EXPECT_EQ(d.durable_version(), d.persists() ? 1u : 0u);
  std::vector<TileKey> stored;
  d.StoredIn({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX}, &stored);
  EXPECT_EQ(stored.size(), d.persists() ? seen : 0u);
}

TYPED_TEST(DurabilityContract, TheExportSourceHoldsTheRangeAsOfTheBarrier) {
  this->Apply(1, Ground(this->params_, 0), 1);
  this->Apply(2, Ground(this->params_, 6), 2);
  ASSERT_TRUE(this->CheckpointAll(2).ok());
  const std::vector<TileKey> all = this->copies_.ListTiles({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX});
  ASSERT_GE(all.size(), 2u);
  const TileKey min = all.front(), max = {all.front().x, INT_MAX};
  std::vector<TileKey> expected = this->copies_.ListTiles(min, max);
  Result<std::unique_ptr<TilesAtVersion>> source =
      this->durability_->OpenTileSource(min, max, this->copies_);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  const std::vector<std::unique_ptr<Tile>> at_barrier = this->copies_.CopyTiles(expected);
  // The map changes on after the barrier (the same ground again, over these tiles); the source
  // does not.
  this->Apply(3, Ground(this->params_, 0), 3);
  const std::vector<std::unique_ptr<Tile>> after = this->copies_.CopyTiles(expected);
  size_t changed = 0;
  for (size_t i = 0; i < expected.size(); ++i) {
    changed += storage::EncodeTile(*after[i]) != storage::EncodeTile(*at_barrier[i]) ? 1 : 0;
  }
  ASSERT_GT(changed, 0u) << "the change after the barrier must reach the range";
  ASSERT_EQ((*source)->keys(), expected);
  for (size_t i = 0; i < expected.size(); ++i) {
    Result<std::unique_ptr<Tile>> tile = (*source)->Take(i);
    ASSERT_TRUE(tile.ok()) << tile.status().ToString();
    ASSERT_NE(*tile, nullptr);
    EXPECT_EQ(storage::EncodeTile(**tile), storage::EncodeTile(*at_barrier[i]))
        << "tile " << i << " as of the barrier, not as changed after it";
  }
}

TYPED_TEST(DurabilityContract, AGeoreferenceIsKeptOnceGiven) {
  Durability& d = *this->durability_;
  EXPECT_TRUE(d.georeference().empty());
  EXPECT_TRUE(d.AdoptGeoreference({}).ok());
  const Georeference utm{"EPSG:32610", {500000, 4100000, 10}};
  ASSERT_TRUE(d.AdoptGeoreference(utm).ok());
  EXPECT_EQ(d.georeference(), utm);
  EXPECT_TRUE(d.AdoptGeoreference(utm).ok());
  const Status other = d.AdoptGeoreference({"EPSG:32611", utm.origin});
  EXPECT_EQ(other.code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(other.message().find("georeference.crs"), std::string::npos) << other.message();
  EXPECT_EQ(d.georeference(), utm);
}

TYPED_TEST(DurabilityContract, CorrectionsNeedRetainedScans) {
  Durability& d = *this->durability_;
  this->Apply(1, Ground(this->params_, 0), 1);
  EXPECT_FALSE(d.retains_scans());
  Result<CorrectionPlan> plan = d.PlanCorrection("r", {{1, Pose{}}}, std::nullopt);
  EXPECT_EQ(plan.status().code(), Status::Code::kFailedPrecondition) << plan.status().ToString();
}

TYPED_TEST(DurabilityContract, TheScratchDirectoryTakesAnImportsSpool) {
  Durability& d = *this->durability_;
  const Durability::ScratchDirectory dir = d.scratch_directory();
  ASSERT_FALSE(dir.path.empty());
  EXPECT_TRUE(d.AdmitScratch(1 << 20).ok());
  std::error_code ec;
  std::filesystem::create_directories(dir.path, ec);
  EXPECT_TRUE(std::filesystem::is_directory(dir.path)) << dir.path;
  EXPECT_EQ(dir.exclusive, d.persists()) << "only a store's own directory is this server's alone";
}

}  // namespace
}  // namespace bgkmap
