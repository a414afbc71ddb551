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

// The features less what the poses' vertical error (`sigma_z`, one sigma per scan) alone makes
// of flat ground seen by several scans: the step less 2 sqrt(2) sigma_z (two scans' heights
// differ by sqrt(2) sigma_z; the neighbourhood's extreme pair by about twice that), the roughness
// less sigma_z in quadrature, neither below 0. sigma_z 0 returns `f` unchanged.
TerrainFeatures DiscountPoseNoise(TerrainFeatures f, double sigma_z);
// DiscountPoseNoise's step alone (the same arithmetic, for a step known before the plane fit).
double DiscountStep(double step, double sigma_z);

// v = w_step h/h_crit + w_slope s/s_crit + w_rough r/r_crit, 1 if any criterion exceeds its
// critical value, clamped to [0, 1].
double TraversabilityValue(const TerrainFeatures& f, const MapParams& params);

// The most height one scan's points in a single cell may span and still lie on traversable
// ground: a critical step plus what a critical slope rises across the cell's diagonal
// (semantics 6, "A step inside a cell"). A cell whose points span more holds a face.
double InCellStepLimit(const MapParams& params);

}  // namespace bgkmap
