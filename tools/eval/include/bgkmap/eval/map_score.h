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
};

// `truth` needs layers kElevation and kState (stride 1, the map's resolution).
MapScore ScoreMap(const TerrainMap& map, const Raster& truth);

}  // namespace bgkmap::eval
