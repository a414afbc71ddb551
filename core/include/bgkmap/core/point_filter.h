// What PrepareScan's filters do with one point of a sensor scan (not frame_is_map) before
// binning, with the same arithmetic (semantics 1 of docs/semantics.md): a client drops the points
// the map drops anyway before sending them, and the map is the same.
#pragma once

#include <cmath>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap {

// Non-finite, outside [min_range, max_range] or inside the self-filter box (kRange: too close,
// the robot's own body), higher than max_height_above_sensor above the sensor, or kept for
// binning (where it may still fall out of bounds).
enum class PointFilter { kKept, kNonFinite, kRange, kHeight };

// Whether the self-filter is on: self_filter_below > 0 and the footprint box set.
inline bool SelfFilterOn(const MapParams& p) {
  return p.self_filter_below > 0 && p.footprint_length > 0 && p.footprint_width > 0;
}

// Whether sensor-frame point `ps` lies in the robot's own box (docs/semantics.md, "Per scan", 1);
// call only when SelfFilterOn(p). Inline: PrepareScan and every client decide with these bits.
inline bool InSelfFilterBox(const MapParams& p, const Eigen::Vector3d& ps) {
  const double half_length = 0.5 * p.footprint_length + p.self_filter_margin;
  const double half_width = 0.5 * p.footprint_width + p.self_filter_margin;
  return std::abs(ps.x() + p.footprint_sensor_x) <= half_length &&
         std::abs(ps.y() + p.footprint_sensor_y) <= half_width && ps.z() >= -p.self_filter_below;
}

PointFilter FilterSensorPoint(const MapParams& params, const Pose& T_map_sensor, const Point3f& p);

}  // namespace bgkmap
