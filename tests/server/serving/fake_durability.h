// A Durability that keeps its "store" in memory, for tests of the serving layer without RocksDB
// or gRPC: it persists (so tiles can be evicted and loaded back), journals into a vector, and
// can be told to refuse records or checkpoint writes, or to report tiles as corrupt.
#pragma once

#include <map>
#include <mutex>
#include <set>

#include "durability/durability.h"

namespace bgkmap::testing {

class FakeDurability final : public Durability {
 public:
  explicit FakeDurability(const MapParams& params)
      : geometry_(params.resolution, params.tile_size) {}

  bool persists() const override { return true; }
  uint64_t recovered_version() const override { return 0; }
  std::map<std::string, uint64_t> LoggedRobotSequences() const override { return {}; }
  Status RetireRobot(const std::string&) override { return Status::Ok(); }
  Georeference georeference() const override { return {}; }
  Status AdoptGeoreference(const Georeference&) override { return Status::Ok(); }

  Status Record(const ChangeRecord& change) override {
    std::lock_guard lock(mu_);
    if (fail_record) return Status::IoError("disk full (fake)");
    recorded.push_back(change.version);
    return Status::Ok();
  }

  Status WriteCheckpoint(uint64_t version, std::span<const TileKey> keys,
                         std::span<const std::unique_ptr<Tile>> tiles) override {
    std::lock_guard lock(mu_);
    if (fail_write) {
      failed_ = true;
      return Status::IoError("checkpoint refused (fake)");
    }
    for (size_t i = 0; i < keys.size(); ++i) {
      if (tiles[i] == nullptr || tiles[i]->Empty()) {
        stored_.erase(keys[i]);
      } else {
        stored_.insert_or_assign(keys[i], std::make_unique<Tile>(*tiles[i]));
      }
    }
    checkpoints.push_back({version, std::vector<TileKey>(keys.begin(), keys.end())});
    durable_ = std::max(durable_, version);
    return Status::Ok();
  }
  bool write_failed() const override {
    std::lock_guard lock(mu_);
    return failed_;
  }
  Status Resume() override {
    std::lock_guard lock(mu_);
    ++resumes;
    if (fail_write) return Status::IoError("still refused (fake)");
    failed_ = false;
    return Status::Ok();
  }

  Result<std::unique_ptr<TilesAtVersion>> OpenTileSource(TileKey, TileKey,
                                                         const ResidentTiles&) override {
    return Status::IoError("not used by these tests");
  }
  std::vector<TileKey> CorruptTiles() const override {
    std::lock_guard lock(mu_);
    return {corrupt.begin(), corrupt.end()};
  }
  ScratchDirectory scratch_directory() const override { return {"/tmp", false}; }
  VerifyReport VerifyStoredTiles(const std::atomic<bool>&) const override { return {}; }
  std::optional<StoreStatus> store_status(bool) const override { return StoreStatus{}; }

  bool IsStored(TileKey key) const override {
    std::lock_guard lock(mu_);
    return stored_.contains(key);
  }
  void StoredIn(TileKey min, TileKey max, std::vector<TileKey>* keys) const override {
    std::lock_guard lock(mu_);
    for (const auto& [k, _] : stored_) {
      if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) keys->push_back(k);
    }
  }
  void ForEachStored(const std::function<void(TileKey, const TileSummary&)>& fn) const override {
    std::lock_guard lock(mu_);
    for (const auto& [k, t] : stored_) fn(k, SummarizeTile(geometry_, k, t.get()));
  }
  std::optional<TileSummary> StoredSummary(TileKey key) const override {
    std::lock_guard lock(mu_);
    auto it = stored_.find(key);
    if (it == stored_.end()) return std::nullopt;
    return SummarizeTile(geometry_, key, it->second.get());
  }
  Result<std::unique_ptr<Tile>> Load(TileKey key) const override {
    std::lock_guard lock(mu_);
    ++loads;
    if (corrupt.contains(key)) return Status::DataLoss("tile fails its checksum (fake)");
    auto it = stored_.find(key);
    if (it == stored_.end()) return std::unique_ptr<Tile>();
    return std::make_unique<Tile>(*it->second);
  }
  uint64_t durable_version() const override {
    std::lock_guard lock(mu_);
    return durable_;
  }

  struct Written {
    uint64_t version;
    std::vector<TileKey> keys;
  };
  // Set and read by tests; guarded by mu_ where the map's workers touch them.
  bool fail_record = false;
  bool fail_write = false;
  std::set<TileKey> corrupt;
  std::vector<uint64_t> recorded;
  std::vector<Written> checkpoints;
  int resumes = 0;
  mutable int loads = 0;

  std::mutex& mu() const { return mu_; }

 private:
  const GridGeometry geometry_;
  mutable std::mutex mu_;
  bool failed_ = false;
  uint64_t durable_ = 0;
  std::map<TileKey, std::unique_ptr<Tile>> stored_;
};

}  // namespace bgkmap::testing
