// Step height, slope and roughness of a terrain patch, and the traversability training value
// v of paper Eq. 5.
#pragma once

#include <span>

#include "bgkmap/core/map_params.h"

namespace bgkmap {

struct PatchPoint {
  double x, y, z;  // cell centre and elevation (any common origin)
};

struct TerrainFeatures {
  double step;       // max - min elevation, metres
  double slope_deg;  // acos(|n_z|) of the PCA plane normal, degrees
  double roughness;  // sqrt of the smallest eigenvalue of the population covariance, metres
};

// Requires at least 3 points.
TerrainFeatures ComputeFeatures(std::span<const PatchPoint> patch);

// v = w_step h/h_crit + w_slope s/s_crit + w_rough r/r_crit, 1 if any criterion exceeds its
// critical value, clamped to [0, 1].
double TraversabilityValue(const TerrainFeatures& f, const MapParams& params);

}  // namespace bgkmap
