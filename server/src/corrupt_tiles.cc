#include "corrupt_tiles.h"

#include <algorithm>
#include <string>

namespace bgkmap {
namespace {

grpc::Status DataLoss(TileKey k) {
  return {grpc::StatusCode::DATA_LOSS,
          "tile (" + std::to_string(k.x) + ", " + std::to_string(k.y) +
              ") of the stored map is corrupt: its cells cannot be answered"};
}

}  // namespace

grpc::Status CheckNoCorruptTile(const ServiceContext& ctx, const CellBox& box) {
  if (ctx.persistence == nullptr) return grpc::Status::OK;
  const GridGeometry& g = ctx.store.geometry();
  const TileKey lo = g.TileOf(box.min), hi = g.TileOf(box.max);
  for (TileKey k : ctx.persistence->CorruptTiles()) {
    if (k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y) return DataLoss(k);
  }
  return grpc::Status::OK;
}

grpc::Status CheckNoCorruptTile(const ServiceContext& ctx, std::span<const CellIndex> cells) {
  if (ctx.persistence == nullptr) return grpc::Status::OK;
  const std::vector<TileKey> corrupt = ctx.persistence->CorruptTiles();  // sorted
  if (corrupt.empty()) return grpc::Status::OK;
  const GridGeometry& g = ctx.store.geometry();
  for (CellIndex c : cells) {
    const TileKey k = g.TileOf(c);
    if (std::binary_search(corrupt.begin(), corrupt.end(), k)) return DataLoss(k);
  }
  return grpc::Status::OK;
}

}  // namespace bgkmap
