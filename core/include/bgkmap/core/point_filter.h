// What PrepareScan's filters do with one point of a sensor scan (not frame_is_map) before
// binning, with the same arithmetic (semantics 1 of docs/semantics.md): a client drops the points
// the map drops anyway before sending them, and the map is the same.
#pragma once

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap {

// Non-finite, outside [min_range, max_range], higher than max_height_above_sensor above the
// sensor, or kept for binning (where it may still fall out of bounds).
enum class PointFilter { kKept, kNonFinite, kRange, kHeight };

PointFilter FilterSensorPoint(const MapParams& params, const Pose& T_map_sensor, const Point3f& p);

}  // namespace bgkmap
