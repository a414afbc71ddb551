#include "rpc/region_delta.h"

#include <algorithm>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/tile_blocks.h"
#include "bgkmap/proto/region_delta_codec.h"

namespace bgkmap {
namespace {

// The pixels of `box` (inside `r`, stride 1) as a raster of their own.
Raster Crop(const Raster& r, const CellBox& box) {
  Raster out = RasterGeometry(r.resolution, box, r.layers, 1);
  const int64_t row0 = r.box.max.y - box.max.y, col0 = box.min.x - r.box.min.x;
  for (const std::vector<float>& layer : r.data) {
    std::vector<float>& dst = out.data.emplace_back(static_cast<size_t>(out.rows * out.cols));
    for (int64_t row = 0; row < out.rows; ++row) {
      const float* from = layer.data() + (row0 + row) * r.cols + col0;
      std::copy(from, from + out.cols, dst.data() + row * out.cols);
    }
  }
  return out;
}

// The changed blocks of `tile` (stride 1) as patches cut from `part`, its pixels in the region:
// per block row, one patch per run of changed blocks, with the rows below that change the
// same blocks joined to it.
void AppendBlockPatches(const GridGeometry& g, const CellBox& region, const ChangedTile& tile,
                        const Raster& part, std::vector<v1::TilePatch>* out) {
  auto row_bits = [&](int by) { return tile.blocks.Row(by); };
  for (int by = 0; by < kTileBlocksPerSide;) {
    const unsigned bits = row_bits(by);
    int by_end = by;
    while (by_end + 1 < kTileBlocksPerSide && row_bits(by_end + 1) == bits) ++by_end;
    for (int bx = 0; bx < kTileBlocksPerSide;) {
      if (!(bits >> bx & 1u)) {
        ++bx;
        continue;
      }
      int bx_end = bx;
      while (bx_end + 1 < kTileBlocksPerSide && (bits >> (bx_end + 1) & 1u)) ++bx_end;
      const CellBox box = TileBlockCells(g, tile.key, bx, by, bx_end, by_end).Intersect(part.box);
      if (!box.empty()) ToProto(tile.key, region, Crop(part, box), &out->emplace_back());
      bx = bx_end + 1;
    }
    by = by_end + 1;
  }
}

}  // namespace

Result<DeltaAnswer> ReadRegionDelta(MapPort& map, const DeltaQuery& q, uint64_t version) {
  DeltaAnswer answer;
  if (q.since_history_id != 0 && q.since_history_id != map.history_id()) {
    answer.resync_reason =
        "since_history_id is not this server's history_id (it restarted, or the answer came "
        "from another server): versions are not comparable";
    return answer;
  }
  if (q.since > version) {
    answer.resync_reason = "since_version " + std::to_string(q.since) +
                           " is ahead of this map's version " + std::to_string(version) +
                           ": it is not one of this map's versions";
    return answer;
  }
  const GridGeometry& g = map.geometry();
  Result<std::vector<ChangedTile>> changed =
      map.TilesChangedSince(g.TileOf(q.region.min), g.TileOf(q.region.max), q.since);
  if (!changed.ok()) {
    answer.resync_reason = changed.status().message();
    return answer;
  }
  answer.patches.reserve(changed->size());
  for (const ChangedTile& tile : *changed) {
    if (tile.blocks.Empty()) continue;  // listed, but nothing in it changed
    const CellBox cells = TilePatchCells(g, q.region, q.stride, tile.key);
    if (cells.empty()) continue;
    Result<Raster> part = map.ReadRegion(cells, q.layers, q.stride);
    if (!part.ok()) return part.status();
    if (q.stride != 1 || tile.blocks.IsAll() || TileBlockShift(g.tile_size()) < 0) {
      ToProto(tile.key, q.region, *part, &answer.patches.emplace_back());
      continue;
    }
    AppendBlockPatches(g, q.region, tile, *part, &answer.patches);
  }
  return answer;
}

}  // namespace bgkmap
