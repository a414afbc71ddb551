// Ground truth for evaluation: the true elevation of the world's surface at cell centres, the
// traversability computed on that true surface with the map's own parameters and formula
// (ComputeFeatures / TraversabilityValue over the same robot-radius neighbourhood), and the area
// a dense set of ground-truth scans sees (the paper scanned every 0.1 m for its ground truth).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

// The cells of `box` observed by a set of scans, under the same filters as mapping (PrepareScan).
class VisibilityMask {
 public:
  VisibilityMask(const MapParams& params, const CellBox& box);

  // Fails only on an invalid pose.
  Status AddScan(std::span<const Point3f> points, const Pose& T_map_sensor);
  void Merge(const VisibilityMask& other);  // same params and box
  void Mark(CellIndex c) {                  // counts `c` as seen (nothing outside the box)
    if (box_.Contains(c))
      seen_[static_cast<size_t>(c.y - box_.min.y) * box_.width() + (c.x - box_.min.x)] = 1;
  }

  const CellBox& box() const { return box_; }
  bool visible(CellIndex c) const {
    return box_.Contains(c) &&
           seen_[static_cast<size_t>(c.y - box_.min.y) * box_.width() + (c.x - box_.min.x)];
  }
  int64_t count() const;

 private:
  MapParams params_;
  CellBox box_;
  std::vector<uint8_t> seen_;
};

// Layers kElevation, kTraversability and kState over the mask's box (stride 1), NaN outside the
// visible area. A cell whose neighbourhood holds fewer than 3 surface samples is non-traversable.
// The traversability of the surface is eval::TruthFromHeights, shared with the truth of real
// scans (eval/scan_truth.h).
Raster MakeGroundTruth(const World& world, const MapParams& params, const VisibilityMask& visible);

}  // namespace bgkmap::sim
