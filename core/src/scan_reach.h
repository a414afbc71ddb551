// Which tiles a prepared scan writes, reads and may clear: the reach of its kernel, of its
// step/slope/roughness patches and of its free-space rays ("within l" is defined here, "within
// robot_radius" in cell_shapes.h, both shared with the integrator so the two always agree).
#pragma once

#include <cmath>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap::internal {

// Cell offset inside the kernel support: centre distance d < l.
inline bool InKernelSupport(int dx, int dy, double resolution, double kernel_length) {
  return resolution * std::hypot(dx, dy) < kernel_length;
}

// Fills scan.write_tiles, scan.read_tiles and scan.clear_tiles from scan.cells (and the sensor).
void ComputeScanTiles(const MapParams& params, PreparedScan& scan);

}  // namespace bgkmap::internal
