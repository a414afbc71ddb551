// Durability of a map served from memory only (no storage.data_dir): nothing is journaled or
// stored, every call succeeds, and an export reads copies of the tiles taken at its barrier.
#pragma once

#include <mutex>

#include "durability/durability.h"

namespace bgkmap {

class MemoryDurability final : public Durability {
 public:
  // `georeference`: the configured one (server config `georeference`), empty for a local frame.
  explicit MemoryDurability(Georeference georeference = {})
      : georeference_(std::move(georeference)) {}

  bool persists() const override { return false; }
  uint64_t recovered_version() const override { return 0; }
  std::map<std::string, uint64_t> LoggedRobotSequences() const override { return {}; }
  Status RetireRobot(const std::string&) override { return Status::Ok(); }
  Status Record(const ChangeRecord&) override { return Status::Ok(); }
  Status WriteCheckpoint(uint64_t, std::span<const TileKey>,
                         std::span<const std::unique_ptr<Tile>>) override {
    return Status::Ok();
  }
  bool write_failed() const override { return false; }
  Status Resume() override { return Status::Ok(); }
  Result<std::unique_ptr<TilesAtVersion>> OpenTileSource(TileKey min, TileKey max,
                                                         const ResidentTiles& map) override;
  std::vector<TileKey> CorruptTiles() const override { return {}; }
  ScratchDirectory scratch_directory() const override;
  VerifyReport VerifyStoredTiles(const std::atomic<bool>&) const override { return {}; }
  std::optional<StoreStatus> store_status(bool) const override { return std::nullopt; }
  Georeference georeference() const override {
    std::lock_guard lock(georeference_mu_);
    return georeference_;
  }
  Status AdoptGeoreference(const Georeference& georeference) override;

  // StoredTiles: nothing is stored, and nothing in memory is ever clean.
  bool IsStored(TileKey) const override { return false; }
  void StoredIn(TileKey, TileKey, std::vector<TileKey>*) const override {}
  void ForEachStored(const std::function<void(TileKey, const TileSummary&)>&) const override {}
  std::optional<TileSummary> StoredSummary(TileKey) const override { return std::nullopt; }
  Result<std::unique_ptr<Tile>> Load(TileKey) const override { return std::unique_ptr<Tile>(); }
  uint64_t durable_version() const override { return 0; }

 private:
  mutable std::mutex georeference_mu_;
  Georeference georeference_;  // guarded by georeference_mu_
};

}  // namespace bgkmap
