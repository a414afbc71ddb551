// Pose error like a real SLAM's, for the map's robustness to it (docs/results.md, "Real
// drives"): each pose is the true one perturbed by independent per-scan jitter (registration
// noise) plus a slow drift of height, roll and pitch (what a SLAM's vertical estimate wanders
// by between corrections). Unlike sim/odometry_drift.h (relative motions perturbed and chained:
// error growing with distance), the error here stays bounded, as after a SLAM back end.
// Deterministic for a seed.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/scan.h"

namespace bgkmap::sim {

struct PoseNoiseOptions {
  // Per scan, independent Gaussian standard deviations.
  double xy_m = 0.03;           // each horizontal axis
  double z_m = 0.03;            // vertical
  double roll_pitch_deg = 0.1;  // each of roll and pitch
  double yaw_deg = 0.1;
  // Slow drift: for each of z, roll and pitch a first-order Gauss-Markov process with this
  // stationary standard deviation and correlation time (in scans): x_{k+1} = a x_k +
  // sqrt(1 - a^2) sigma n_k, a = exp(-1 / drift_scans), x_0 ~ N(0, sigma^2).
  double drift_z_m = 0.05;
  double drift_roll_pitch_deg = 0.2;
  double drift_scans = 100.0;
  uint32_t seed = 1;

  // Every size multiplied by `s` (0: no error; 1: the defaults, realistic).
  PoseNoiseOptions Scaled(double s) const;
};

// The perturbed poses, one per true pose: rotation dR * R (dR from roll, pitch, yaw about the
// map's axes, so roll and pitch tilt the scan against gravity about the sensor), translation t +
// dt.
std::vector<Pose> PerturbPoses(const std::vector<Pose>& truth, const PoseNoiseOptions& options);

}  // namespace bgkmap::sim
