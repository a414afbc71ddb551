// Ground truth from a surface: a height per cell (NaN where the surface is unknown), its
// traversability computed with the map's own parameters and formula (ComputeFeatures /
// TraversabilityValue over the same robot-radius neighbourhood), and the state the threshold
// gives. The simulator's truth (sim/ground_truth.h: the true surface at cell centres) and the
// truth of real scans (eval/scan_truth.h: the raw surface all points of all scans observe) are
// both this function of their surface.
#pragma once

#include <functional>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/raster.h"

namespace bgkmap::eval {

// Heights over a box of cells, row-major from box.min (x fastest), NaN = unknown. A cell outside
// the box is unknown.
struct CellHeights {
  CellBox box;
  std::vector<double> z;

  CellHeights() = default;
  explicit CellHeights(const CellBox& b);  // every cell unknown
  double at(CellIndex c) const {
    return box.Contains(c)
               ? z[static_cast<size_t>(c.y - box.min.y) * box.width() + (c.x - box.min.x)]
               : kUnknown;
  }
  void set(CellIndex c, double height) {
    z[static_cast<size_t>(c.y - box.min.y) * box.width() + (c.x - box.min.x)] = height;
  }
  static const double kUnknown;
};

// What a cell whose robot-radius neighbourhood holds fewer than 3 known heights (too few for
// ComputeFeatures) becomes.
enum class SparseNeighbourhood {
  kNonTraversable,  // v = 1 (the simulator: only where its world has no surface)
  kUnknown,         // NaN on every layer (real scans: too little evidence to judge)
};

// Layers kElevation, kTraversability and kState over `box` (stride 1). A cell is judged only if
// judged(cell) holds and its own height is known; every other cell is NaN on every layer. The
// neighbourhood of a cell is DiskOffsets(robot_radius, resolution) around it, read from
// `heights` (which should cover `box` grown by robot_radius to see every neighbour).
Raster TruthFromHeights(const CellHeights& heights, const CellBox& box, const MapParams& params,
                        const std::function<bool(CellIndex)>& judged, SparseNeighbourhood sparse);

// The largest |dx| or |dy| of DiskOffsets(robot_radius, resolution): how many cells a box must
// grow by for TruthFromHeights to see every neighbour of its cells.
int NeighbourhoodPad(const MapParams& params);

}  // namespace bgkmap::eval
