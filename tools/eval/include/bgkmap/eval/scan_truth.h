// Ground truth for real scans (issue 14, docs/results.md "Real street scans"): what ALL points of
// ALL scans of a sequence observe, judged with the map's own rules. The paper's truth came from
// scanning more densely than the map did; for a real sequence the densest data there is is the
// whole sequence, and the map under test is given a sparser part of it (`bgkmap thin`).
//
// Per cell, the raw observed elevation: the map's observation rule (`observation: max | mean`)
// applied to every point of every scan that falls in the cell, under the same filters as mapping
// (each point goes through the public PrepareScan, so range, height-above-sensor, non-finite and
// bounds filters are exactly the map's). Only cells with at least `min_points` such points are
// part of the truth's surface. Traversability and state are eval::TruthFromHeights on that
// surface, as the simulator's truth on the true surface, except that a cell with fewer than 3
// known heights within robot_radius is unknown (not judged), not non-traversable.
#pragma once

#include <cstdint>
#include <span>
#include <unordered_map>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/eval/surface_truth.h"

namespace bgkmap::eval {

struct ScanTruthOptions {
  // Points a cell needs, over all scans, to be part of the truth's surface. The default 2: one
  // return is the least any map could be given, so the truth asks for at least twice that.
  int min_points = 2;
};

struct ScanTruthStats {
  uint64_t scans = 0;
  uint64_t points_input = 0;
  uint64_t points_kept = 0;     // after the mapping filters
  int64_t observed_cells = 0;   // cells with at least one kept point
  int64_t supported_cells = 0;  // cells with at least min_points: the truth's surface
  int64_t judged_cells = 0;     // supported cells with >= 3 known heights within robot_radius
  int64_t traversable_cells = 0;
  int64_t non_traversable_cells = 0;
};

class ScanTruthBuilder {
 public:
  explicit ScanTruthBuilder(const MapParams& params, ScanTruthOptions options = {});

  // Adds one scan's points (sensor frame, or map frame with frame_is_map, as PrepareScan).
  // Fails, adding nothing, on an invalid pose.
  Status AddScan(std::span<const Point3f> points, const Pose& T_map_sensor,
                 bool frame_is_map = false);

  // The truth's surface: the observed elevation of every supported cell over their bounding box,
  // NaN elsewhere (empty box if no cell is supported).
  CellHeights Surface() const;
  // Layers kElevation, kTraversability, kState over the surface's box (stride 1), NaN where not
  // judged: what `bgkmap eval --truth` reads.
  Raster Build() const;
  // Counts of the scans added so far and of `truth` (what Build() made).
  ScanTruthStats Stats(const Raster& truth) const;

 private:
  struct Cell {
    uint32_t count = 0;
    double sum = 0;
    double max = 0;
  };
  static uint64_t Key(CellIndex c) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(c.x)) << 32) | static_cast<uint32_t>(c.y);
  }
  MapParams params_;
  MapParams prepare_params_;  // params_ without the footprint: only the points' cells
  ScanTruthOptions options_;
  std::unordered_map<uint64_t, Cell> cells_;
  uint64_t scans_ = 0, input_ = 0, kept_ = 0;
};

}  // namespace bgkmap::eval
