// The tiles in memory as the durability copies them at a barrier (checkpoints, exports).
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "durability/durability.h"
#include "serving/tile_table.h"

namespace bgkmap {

class TableCopies final : public ResidentTiles {
 public:
  explicit TableCopies(const TileTable& table) : table_(table) {}
  std::vector<std::unique_ptr<Tile>> CopyTiles(std::span<const TileKey> keys) const override {
    return table_.CopyTiles(keys);
  }
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const override {
    return table_.ListTiles(min, max);
  }

 private:
  const TileTable& table_;
};

}  // namespace bgkmap
