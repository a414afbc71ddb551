// Casts every beam of a model from a sensor pose into a World and returns the returns in the
// sensor frame, like a driver would (beams without a return are dropped).
#pragma once

#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/sim/beam_model.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

struct RayCastOptions {
  double step_min = 0.02;     // marching step at the sensor, metres
  double step_per_m = 0.004;  // extra step per metre of range (far surfaces need less detail)
  unsigned seed = 1;          // range-noise generator seed (deterministic scans)
};

// Range along the unit direction `dir` of the first solid point (surface or overhang), bisected to
// 1 mm; NaN if there is none within max_range. Marches with the options' growing step wherever
// the world's height bound (World::MaxHeightIn) does not prove a span of the ray empty.
double CastRay(const World& world, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
               double max_range, const RayCastOptions& options = {});

std::vector<Point3f> SimulateScan(const World& world, const BeamModel& beams,
                                  const Pose& T_world_sensor, const RayCastOptions& options = {});

}  // namespace bgkmap::sim
