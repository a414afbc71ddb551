// How well a map matches the ground truth over the area the ground-truth scans see.
#pragma once

#include <cstdint>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/roc.h"

namespace bgkmap::eval {

struct MapScore {
  int64_t truth_cells = 0;  // visible ground-truth cells (finite truth state)
  int64_t known_cells = 0;  // of those, cells the map knows
  double coverage = 0;      // known / truth
  // Elevation mean squared error over known truth cells, and over those the truth calls
  // traversable (the ground itself: tall obstacles seen only up to the sensor skew the first).
  double mse_all = 0;
  double mse_ground = 0;
  int64_t ground_cells = 0;
  // Traversability mean as a score for "non-traversable" over known truth cells; a known cell
  // without a value scores 1 (the map calls it non-traversable).
  Roc roc;
  double state_accuracy = 0;  // fraction of known truth cells whose state equals the truth
  // What a planner trusting the state layer gets wrong, both over the known truth cells:
  // dangerous misses are truly non-traversable cells the map calls traversable (it would drive
  // into them), false alarms truly traversable cells it calls non-traversable (detours).
  int64_t dangerous_misses = 0;
  int64_t false_alarms = 0;
  double dangerous_miss_rate = 0;  // dangerous_misses / known_cells
  double false_alarm_rate = 0;     // false_alarms / known_cells
};

// `truth` needs layers kElevation and kState (stride 1, the map's resolution).
MapScore ScoreMap(const TerrainMap& map, const Raster& truth);

}  // namespace bgkmap::eval
