// `bgkmap insert --align-z`: each scan's z aligned to the served map before it is sent, the
// robot-side step of core/vertical_alignment.h (docs/mapping-your-robot.md, "Vertical
// alignment") with the map's heights from a region query around the sensor.
#pragma once

#include <cstdint>
#include <span>

#include "bgkmap/client/client.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/vertical_alignment.h"

namespace bgkmap::cli {

struct ServedAlignmentOptions {
  VerticalAlignmentOptions align;
  // Map cells per pixel edge of the region query: the query's bytes fall with its square. A
  // pixel holds its block's pooled elevation (core/raster.h), which each scan cell in the block
  // is compared with.
  int stride = 4;
};

// What the alignment of the scans sent so far did.
struct ServedAlignmentStats {
  uint64_t aligned = 0, not_aligned = 0;
  double sum_abs_dz = 0, max_abs_dz = 0;  // m, over the aligned scans
  uint64_t levelled = 0;                  // aligned scans whose tilt was levelled too
  double max_tilt_deg = 0;                // the largest slope levelled, in x or y
  uint64_t region_bytes = 0;              // the queries' raster payloads (pixels x layers x 4)
  double seconds = 0;                     // preparing, querying and comparing
};

// The map's heights from a region raster of kElevation, kElevationWeight and kState at any
// stride: a cell reads its block's elevation, its block's weight per cell (the block's sum /
// stride^2) and whether the block is traversable.
MapHeightLookup RasterHeights(const Raster& raster);

// The alignment of one scan against the map `client` serves (`params`: the map's, from Info).
// The caller decides what the map holds when it asks (insert waits for the scans before it).
Result<VerticalAlignment> AlignToServedMap(Client& client, const MapParams& params,
                                           std::span<const Point3f> points, const Pose& pose,
                                           const ServedAlignmentOptions& options,
                                           ServedAlignmentStats* stats);

}  // namespace bgkmap::cli
