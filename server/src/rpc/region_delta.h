// Region deltas (docs/server.md, "Region deltas"): which tiles a since_version answer holds,
// and their patches. The map port says which tiles changed; this reads and encodes them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/v1/query.pb.h"
#include "serving/map_port.h"

namespace bgkmap {

struct DeltaQuery {
  CellBox region;  // as RegionCells widened it
  std::vector<Layer> layers;
  int stride = 1;
  uint64_t since = 0;
  uint64_t since_history_id = 0;  // 0: not checked
};

// The patches of every tile of the region changed after `q.since`, each read once the tile's
// change is applied, with `version` (map.applied_version(), read before) the version to ask
// from next. Or why the delta cannot be answered exactly (`resync_reason`, then the caller
// answers the whole region); an error status if a tile cannot be read.
struct DeltaAnswer {
  std::string resync_reason;
  std::vector<v1::TilePatch> patches;
};
Result<DeltaAnswer> ReadRegionDelta(MapPort& map, const DeltaQuery& q, uint64_t version);

}  // namespace bgkmap
