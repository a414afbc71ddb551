#include "bgkmap/sim/ground_truth.h"

#include "bgkmap/eval/surface_truth.h"

namespace bgkmap::sim {

VisibilityMask::VisibilityMask(const MapParams& params, const CellBox& box)
    : params_(params), box_(box), seen_(static_cast<size_t>(box.cell_count()), 0) {}

Status VisibilityMask::AddScan(std::span<const Point3f> points, const Pose& T_map_sensor) {
  Result<PreparedScan> scan = PrepareScan(params_, points, T_map_sensor);
  if (!scan.ok()) return scan.status();
  for (const ObservedCell& oc : scan->cells) {
    if (!box_.Contains(oc.cell)) continue;
    seen_[static_cast<size_t>(oc.cell.y - box_.min.y) * box_.width() + (oc.cell.x - box_.min.x)] =
        1;
  }
  return Status::Ok();
}

void VisibilityMask::Merge(const VisibilityMask& other) {
  for (size_t i = 0; i < seen_.size() && i < other.seen_.size(); ++i) seen_[i] |= other.seen_[i];
}

int64_t VisibilityMask::count() const {
  int64_t n = 0;
  for (uint8_t s : seen_) n += s;
  return n;
}

Raster MakeGroundTruth(const World& world, const MapParams& params, const VisibilityMask& mask) {
  const CellBox& box = mask.box();
  const double res = params.resolution;
  const int pad = eval::NeighbourhoodPad(params);
  // True surface at cell centres over the box grown by the neighbourhood radius.
  eval::CellHeights z(
      CellBox{{box.min.x - pad, box.min.y - pad}, {box.max.x + pad, box.max.y + pad}});
  for (int iy = z.box.min.y; iy <= z.box.max.y; ++iy) {
    for (int ix = z.box.min.x; ix <= z.box.max.x; ++ix) {
      z.set({ix, iy}, world.SurfaceHeight((ix + 0.5) * res, (iy + 0.5) * res));
    }
  }
  return eval::TruthFromHeights(
      z, box, params, [&](CellIndex c) { return mask.visible(c); },
      eval::SparseNeighbourhood::kNonTraversable);
}

}  // namespace bgkmap::sim
