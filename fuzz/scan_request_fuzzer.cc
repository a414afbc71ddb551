// The server's request checks (server/src/rpc/request_checks.h) on arbitrary protobuf bytes,
// with the default map parameters and limits, as the handlers call them:
//   first byte even: the bytes are a v1::Scan for PrepareScanMessage (robot id, packed or
//     compact points, pose; then the engine's scan preparation);
//   first byte odd:  a v1::RegionRequest for LayersFromProto and RegionCells (stride up to
//     QueryRegion's 4096; limited as QueryRegion, unlimited as ClearRegion).
// Never crashes; an accepted scan accounts for every point it was sent, and an accepted region
// is a non-empty, stride-aligned cell box within the cell limit.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/server/server_config.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace {

void CheckScan(const uint8_t* data, size_t size, const bgkmap::MapParams& params,
               const bgkmap::ServerLimits& limits) {
  bgkmap::v1::Scan scan;
  if (!scan.ParseFromArray(data, static_cast<int>(size))) return;
  bgkmap::PreparedScan prepared;
  if (!bgkmap::PrepareScanMessage(scan, params, limits, &prepared).ok()) return;
  const bgkmap::ScanPointCounts& c = prepared.counts;
  const uint64_t sent =
      scan.has_compact_points() ? scan.compact_points().count() : scan.points().size() / 12;
  if (c.input != sent ||
      c.kept + c.dropped_nonfinite + c.dropped_range + c.dropped_height + c.dropped_out_of_bounds !=
          c.input ||
      prepared.cells.size() > c.kept) {
    std::abort();
  }
}

void CheckRegion(const uint8_t* data, size_t size, const bgkmap::GridGeometry& geometry,
                 const bgkmap::ServerLimits& limits) {
  bgkmap::v1::RegionRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return;
  std::vector<bgkmap::Layer> layers;
  if (!bgkmap::LayersFromProto(request.layers(), "layers", &layers).ok()) return;
  if (layers.empty() || layers.size() > static_cast<size_t>(bgkmap::kLayerCount)) std::abort();
  const int stride =
      static_cast<int>(std::min<uint32_t>(std::max<uint32_t>(request.stride(), 1), 4096));
  for (bool limit : {true, false}) {
    bgkmap::CellBox box;
    if (!bgkmap::RegionCells(request.box(), "box", geometry, stride, limits, limit, &box).ok()) {
      continue;
    }
    if (box.empty() || box.width() % stride != 0 || box.height() % stride != 0) std::abort();
    // The limits count output pixels (max_region_cells) and map cells read
    // (max_region_read_cells).
    const uint64_t cells = static_cast<uint64_t>(box.cell_count());
    const uint64_t pixels = cells / (static_cast<uint64_t>(stride) * stride);
    if (limit && (pixels > limits.max_region_cells || cells > limits.max_region_read_cells)) {
      std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bgkmap::MapParams params;
  static const bgkmap::ServerLimits limits;
  static const bgkmap::GridGeometry geometry(params.resolution, params.tile_size);
  if (size < 1) return 0;
  if (data[0] % 2 == 0) {
    CheckScan(data + 1, size - 1, params, limits);
  } else {
    CheckRegion(data + 1, size - 1, geometry, limits);
  }
  return 0;
}
