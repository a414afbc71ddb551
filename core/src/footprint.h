// Which tiles a prepared scan writes and reads, and the cell-offset predicates that define
// "within l" and "within robot_radius" (shared with the integrator so the two always agree).
#pragma once

#include <cmath>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap::internal {

// Cell offset inside the kernel support: centre distance d < l.
inline bool InKernelSupport(int dx, int dy, double resolution, double kernel_length) {
  return resolution * std::hypot(dx, dy) < kernel_length;
}

// Squared-offset limit for "within robot_radius, inclusive": a relative tolerance keeps cells
// exactly at the radius (e.g. radius 0.3 at resolution 0.1) from being lost to rounding.
inline double NeighbourhoodLimit(double radius, double resolution) {
  const double q = radius / resolution;
  return q * q * (1.0 + 1e-9) + 1e-9;
}
inline bool InNeighbourhood(int dx, int dy, double limit) {
  return static_cast<double>(dx) * dx + static_cast<double>(dy) * dy <= limit;
}

// Fills scan.write_tiles, scan.read_tiles and scan.clear_tiles from scan.cells (and the sensor).
void ComputeFootprint(const MapParams& params, PreparedScan& scan);

}  // namespace bgkmap::internal
