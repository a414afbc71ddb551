#include "durability/memory_durability.h"

#include <filesystem>

namespace bgkmap {
namespace {

// Tiles copied at the barrier, handed out one by one.
class CopiedTiles final : public TilesAtVersion {
 public:
  CopiedTiles(std::vector<TileKey> keys, std::vector<std::unique_ptr<Tile>> tiles)
      : keys_(std::move(keys)), tiles_(std::move(tiles)) {}
  const std::vector<TileKey>& keys() const override { return keys_; }
  Result<std::unique_ptr<Tile>> Take(size_t i) override { return std::move(tiles_[i]); }

 private:
  std::vector<TileKey> keys_;
  std::vector<std::unique_ptr<Tile>> tiles_;
};

}  // namespace

Result<std::unique_ptr<TilesAtVersion>> MemoryDurability::OpenTileSource(TileKey min, TileKey max,
                                                                         const ResidentTiles& map) {
  std::vector<TileKey> keys = map.ListTiles(min, max);
  std::vector<std::unique_ptr<Tile>> tiles = map.CopyTiles(keys);
  return std::unique_ptr<TilesAtVersion>(new CopiedTiles(std::move(keys), std::move(tiles)));
}

Status MemoryDurability::AdoptGeoreference(const Georeference& georeference) {
  std::lock_guard lock(georeference_mu_);
  if (Status s = storage::CheckGeoreferenceCompatible(georeference_, georeference); !s.ok()) {
    return s;
  }
  if (georeference_.empty()) georeference_ = georeference;
  return Status::Ok();
}

Durability::ScratchDirectory MemoryDurability::scratch_directory() const {
  return {std::filesystem::temp_directory_path().string(), /*exclusive=*/false};
}

}  // namespace bgkmap
