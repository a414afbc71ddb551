#include "bgkmap/sim/ground_truth.h"

#include <cmath>
#include <limits>

#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_features.h"

namespace bgkmap::sim {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}  // namespace

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
  const std::vector<CellIndex> disk = DiskOffsets(params.robot_radius, res);
  int pad = 0;
  for (const CellIndex& o : disk) pad = std::max({pad, std::abs(o.x), std::abs(o.y)});

  // True surface at cell centres over the box grown by the neighbourhood radius.
  const int64_t pw = box.width() + 2 * pad, ph = box.height() + 2 * pad;
  std::vector<double> z(static_cast<size_t>(pw * ph));
  for (int64_t j = 0; j < ph; ++j) {
    for (int64_t i = 0; i < pw; ++i) {
      z[j * pw + i] =
          world.SurfaceHeight((box.min.x - pad + i + 0.5) * res, (box.min.y - pad + j + 0.5) * res);
    }
  }

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
      if (!mask.visible({ix, iy})) continue;
      const int64_t pi = ix - box.min.x + pad, pj = iy - box.min.y + pad;
      const double zc = z[pj * pw + pi];
      if (std::isnan(zc)) continue;
      patch.clear();
      for (const CellIndex& o : disk) {
        const double zn = z[(pj + o.y) * pw + (pi + o.x)];
        if (!std::isnan(zn)) patch.push_back({o.x * res, o.y * res, zn});
      }
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

}  // namespace bgkmap::sim
