// Vertical alignment of a scan to the map: a ROBOT-side step, not a map rule
// (docs/mapping-your-robot.md, "Vertical alignment").
//
// A localization with a few centimetres of vertical error per scan puts each scan's ground a few
// centimetres above or below the last one's; the map reads those offsets as steps and roughness
// (docs/results.md, "Proposed rules", P1). The map itself must stay a pure function of its scans
// and poses (exact merges, corrections, the cluster replaying its log), so it never moves a scan.
// A robot may: comparing its scan with the map it shares and correcting its pose's z before
// sending is what a localization with vertical drift does. This is that comparison, pure (no
// I/O, no map access of its own): the caller answers the map's heights, from a TerrainMap
// (MapHeightsOf) or from a region query of a served map.
#pragma once

#include <cstddef>
#include <functional>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap {

class TerrainMap;

// The options of the alignment, as data.
struct VerticalAlignmentOptions {
  // Only the scan's cells within this horizontal distance of the sensor are compared: near
  // cells, where a tilt error of the pose moves the scan's height least (0.1 deg is 3.5 cm at
  // 20 m).
  double radius_m = 20.0;
  // A map cell takes part if its elevation weight is at least this many full-kernel
  // observations (FullKernelWeight): an elevation the map has seen at least once.
  double min_map_weight = 1.0;
  // Only cells the map calls traversable take part: flat ground, whose height a scan sees the
  // same from anywhere. A wall's or a tree's cell holds the highest return of each scan, which
  // rises as the robot comes nearer (measured in the simulated City with perfect poses: wall
  // and vegetation cells 9 cm above the map, the ground 0.4 cm below, the median of all 5.5 cm;
  // the first scans' offset then stays in the map as a datum shift).
  bool traversable_only = true;
  // Fewer cells in common than this: no alignment (dz = 0). A median of fewer cells can be the
  // top of one object rather than the ground; 200 cells are 2 m^2 at 0.1 m cells.
  size_t min_cells = 200;
  // A median offset larger than this (m): no alignment (dz = 0). The alignment is for the
  // error of a working localization (centimetres, a few decimetres of drift); an offset beyond
  // this says the scan and the map do not see the same surfaces (a wrong x-y pose, another
  // floor, a changed world), and moving the scan by it would do more harm than leaving it.
  double max_offset_m = 1.0;
  // Experimental, off (0): also the residuals' tilt about the sensor, a least-squares plane
  // through the cells within tilt_inlier_m of the median offset, if its slope is at most this
  // (deg) in x and y; the scan is then turned about the sensor to level it (AlignedPose).
  double max_tilt_deg = 0.0;
  double tilt_inlier_m = 0.1;
};

// The map's elevation at a cell, its elevation weight and whether its state is traversable;
// NaN elevation or weight 0: unknown.
struct MapHeight {
  float elevation;
  float weight;
  bool traversable = true;
};
using MapHeightLookup = std::function<MapHeight(CellIndex)>;

enum class AlignmentOutcome {
  kAligned,      // dz is the median offset
  kNoSensor,     // a cloud in the map frame (frame_is_map) has no pose to correct
  kTooFewCells,  // fewer than min_cells in common (an empty map, the first scan)
  kBeyondBound,  // |median| > max_offset_m
};

struct VerticalAlignment {
  // Subtract from the pose's z (translation.z()): the scan's heights are then the map's. 0
  // unless aligned.
  double dz = 0.0;
  size_t cells = 0;     // the cells compared
  double median = 0.0;  // their median offset, also when it was not applied (0 if no cells)
  // With max_tilt_deg > 0: the residuals' slope along the map's x and y (dz/dx), taken out by
  // AlignedPose's turn about the sensor; dz is then the median offset once it is taken out.
  double slope_x = 0.0, slope_y = 0.0;
  AlignmentOutcome outcome = AlignmentOutcome::kTooFewCells;

  bool Levelled() const { return slope_x != 0 || slope_y != 0; }
  // The larger of the two slopes levelled, as an angle in degrees (0 if none).
  double TiltDegrees() const;
};

// The median of (scan's height - map's elevation) over the scan's observed cells within
// radius_m of the sensor where the map's weight is at least min_map_weight FullKernelWeight(p)
// (and, with traversable_only, the map's state is traversable).
// `scan` is prepared with `p` and the uncorrected pose; the scan's heights are its training
// values (max or mean z of its points per cell), as the map's elevations are made of them.
VerticalAlignment AlignScanVertically(const MapParams& p, const PreparedScan& scan,
                                      const MapHeightLookup& map,
                                      const VerticalAlignmentOptions& options = {});

// The map's heights from a TerrainMap (its Estimate): for the offline tools.
MapHeightLookup MapHeightsOf(const TerrainMap& map);

// `pose` with dz subtracted from its z (and with a tilt, turned about the sensor to level it).
Pose AlignedPose(const Pose& pose, const VerticalAlignment& alignment);

}  // namespace bgkmap
