#include "bgkmap/core/point_filter.h"

#include <cmath>

namespace bgkmap {

PointFilter FilterSensorPoint(const MapParams& params, const Pose& T, const Point3f& p) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return PointFilter::kNonFinite;
  }
  // Computed as PrepareScan computes them (core/src/scan.cc), so both decide alike to the bit.
  const double min_r2 = params.min_range * params.min_range;
  const double max_r2 = params.max_range * params.max_range;
  const Eigen::Vector3d ps(p.x, p.y, p.z);
  const double r2 = ps.squaredNorm();
  if (r2 < min_r2 || r2 > max_r2) return PointFilter::kRange;
  if (SelfFilterOn(params) && InSelfFilterBox(params, ps)) return PointFilter::kRange;
  const double z_limit = T.translation.z() + params.max_height_above_sensor;
  const Eigen::Matrix3d& R = T.rotation;
  const Eigen::Vector3d& t = T.translation;
  const Eigen::Vector3d q = R * ps + t;
  return q.z() > z_limit ? PointFilter::kHeight : PointFilter::kKept;
}

}  // namespace bgkmap
