// Can the robot stand at these poses? The map's answer to a planner's path (docs/server.md
// CheckPath): the cells a footprint covers at a pose (cell_shapes.h's rule) and the verdict on
// them. Pure: the caller reads the cells' estimates from the map.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/cell_shapes.h"
#include "bgkmap/core/grid.h"

namespace bgkmap {

// A planar pose in the map frame: position (m) and heading (rad, counter-clockwise from x).
struct Pose2 {
  double x = 0, y = 0, yaw = 0;
};

// A robot's footprint: the polygon (robot frame, x forward, at least 3 vertices) when it has
// vertices, else the disk of `radius` around the pose.
struct Footprint {
  double radius = 0;
  std::vector<Point2> polygon;

  // The largest distance from the pose to the footprint's edge, metres.
  double Reach() const;
};

// The cells whose centres the footprint covers at `pose`, sorted by (x, y); at least the cell
// under the pose. The caller bounds the pose and the reach so every index fits.
std::vector<CellIndex> FootprintCells(const GridGeometry& grid, const Footprint& footprint,
                                      const Pose2& pose);

// What a pose may have under its footprint to be safe.
struct PathThresholds {
  double max_traversability = 0;           // worst traversability must be below
  double max_traversability_variance = 0;  // its variance must be below
  double max_unknown_fraction = 0;         // at most this share of unknown cells
};

// One pose's verdict: the worst known traversability under the footprint (the highest, ties
// broken by the higher variance; NaN when every cell is unknown), its variance, the share of
// unknown cells, and whether all three pass the thresholds.
struct PoseCheck {
  float worst_traversability = 0;
  float worst_traversability_variance = 0;
  float unknown_fraction = 0;
  uint32_t cell_count = 0;
  bool safe = false;
};

// The verdict on the estimates of one footprint's cells (at least one).
PoseCheck JudgeFootprint(std::span<const CellEstimate> cells, const PathThresholds& thresholds);

}  // namespace bgkmap
