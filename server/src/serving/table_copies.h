// The tiles in memory as the durability copies them at a barrier (checkpoints, exports),
// packed: a checkpoint holds its copies until they are written, and under a memory bound they
// would otherwise cost a dense tile each for a few known cells.
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
    return table_.CopyTilesPacked(keys);
  }
  std::vector<TileKey> ListTiles(TileKey min, TileKey max) const override {
    return table_.ListTiles(min, max);
  }

 private:
  const TileTable& table_;
};

}  // namespace bgkmap
