#include "rpc/region_delta.h"

#include "bgkmap/core/raster.h"
#include "bgkmap/proto/region_delta_codec.h"

namespace bgkmap {

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
  Result<std::vector<TileKey>> changed =
      map.TilesChangedSince(g.TileOf(q.region.min), g.TileOf(q.region.max), q.since);
  if (!changed.ok()) {
    answer.resync_reason = changed.status().message();
    return answer;
  }
  answer.patches.reserve(changed->size());
  for (TileKey key : *changed) {
    const CellBox cells = TilePatchCells(g, q.region, q.stride, key);
    if (cells.empty()) continue;
    Result<Raster> part = map.ReadRegion(cells, q.layers, q.stride);
    if (!part.ok()) return part.status();
    ToProto(key, q.region, *part, &answer.patches.emplace_back());
  }
  return answer;
}

}  // namespace bgkmap
