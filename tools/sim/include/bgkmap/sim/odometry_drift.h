// Odometry that drifts, for pose-correction tests and results: the true trajectory's relative
// motions, each perturbed by noise proportional to the distance moved, chained from the first
// true pose. Deterministic for a seed.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/scan.h"

namespace bgkmap::sim {

struct DriftOptions {
  // Standard deviation of the position error per metre moved, in each horizontal axis (0.01:
  // 1 % of distance, typical wheel odometry); a fifth of it vertically.
  double translation_per_m = 0.01;
  // Standard deviation of the heading error per metre moved, radians.
  double yaw_per_m = 0.002;
  uint32_t seed = 1;
};

// The drifted poses, one per true pose (the first is the first true pose).
std::vector<Pose> DriftedOdometry(const std::vector<Pose>& truth, const DriftOptions& options);

}  // namespace bgkmap::sim
