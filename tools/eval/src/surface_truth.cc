#include "bgkmap/eval/surface_truth.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_features.h"

namespace bgkmap::eval {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}  // namespace

const double CellHeights::kUnknown = std::numeric_limits<double>::quiet_NaN();

CellHeights::CellHeights(const CellBox& b)
    : box(b), z(static_cast<size_t>(b.cell_count()), kUnknown) {}

int NeighbourhoodPad(const MapParams& params) {
  int pad = 0;
  for (const CellIndex& o : DiskOffsets(params.robot_radius, params.resolution)) {
    pad = std::max({pad, std::abs(o.x), std::abs(o.y)});
  }
  return pad;
}

Raster TruthFromHeights(const CellHeights& heights, const CellBox& box, const MapParams& params,
                        const std::function<bool(CellIndex)>& judged, SparseNeighbourhood sparse) {
  const double res = params.resolution;
  const std::vector<CellIndex> disk = DiskOffsets(params.robot_radius, res);
  Raster r;
  r.box = box;
  r.stride = 1;
  r.cols = box.width();
  r.rows = box.height();
  r.resolution = res;
  r.x0 = box.min.x * res;
  r.y1 = (box.max.y + 1) * res;
  r.layers = {Layer::kElevation, Layer::kTraversability, Layer::kState};
  r.data.assign(3, std::vector<float>(static_cast<size_t>(r.cols * r.rows), kNaN));
  std::vector<PatchPoint> patch;
  for (int64_t row = 0; row < r.rows; ++row) {
    const int iy = box.max.y - static_cast<int>(row);
    for (int64_t col = 0; col < r.cols; ++col) {
      const int ix = box.min.x + static_cast<int>(col);
      if (!judged({ix, iy})) continue;
      const double zc = heights.at({ix, iy});
      if (std::isnan(zc)) continue;
      patch.clear();
      for (const CellIndex& o : disk) {
        const double zn = heights.at({ix + o.x, iy + o.y});
        if (!std::isnan(zn)) patch.push_back({o.x * res, o.y * res, zn});
      }
      if (patch.size() < 3 && sparse == SparseNeighbourhood::kUnknown) continue;
      const double v =
          patch.size() >= 3 ? TraversabilityValue(ComputeFeatures(patch), params) : 1.0;
      const size_t k = static_cast<size_t>(row * r.cols + col);
      r.data[0][k] = static_cast<float>(zc);
      r.data[1][k] = static_cast<float>(v);
      r.data[2][k] = static_cast<float>(v < params.trav_threshold ? CellState::kTraversable
                                                                  : CellState::kNonTraversable);
    }
  }
  return r;
}

}  // namespace bgkmap::eval
