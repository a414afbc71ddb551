// A region too large for one QueryRegion, read in pieces and stitched into one raster. The rule
// mirrors the Python client's (client/python/bgkmap/_codec.py, split_region): pieces of whole
// pixel blocks aligned with the global stride grid, north first, each within the server's
// budget, covering exactly the cells the server would read for the whole box.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

// More pieces than this and the box is sent whole, for the server to name its limit.
inline constexpr size_t kMaxRegionPieces = 256;

// The map cells one region query may read at `stride`: max_region_cells pixels x stride^2,
// within max_region_read_cells; an older server (no max_region_read_cells) counted map cells.
uint64_t RegionCellBudget(const ServerLimitsInfo& limits, int stride);

// More windows than this (RegionWindows) and the box is sent whole, for the server to name its
// limit: 100,000 windows of 1536 x 1536 pixels are 2,400 km² at 0.1 m, days of reading.
inline constexpr size_t kMaxRegionWindows = 100'000;

// The cells the server reads for `box` at `stride`: its half-open cells (GridGeometry's
// CellsOfInterval) widened to whole stride blocks; the box of the answer's raster. Empty for an
// empty or invalid box.
CellBox RegionCells(const MetricBox& box, double resolution, int stride);

// The region of `box` at `stride` cut into windows of at most `window` x `window` pixels, counted
// from the region's north-west pixel (so a raster tiled in blocks whose edge divides `window` gets
// whole blocks from each window), rows of windows north first, each west to east. Each window
// is a box of exactly its cells (RegionCells of it is the window's cells). {box} when it is
// empty or invalid, `window` < 1, or it would take more than kMaxRegionWindows windows.
std::vector<MetricBox> RegionWindows(const MetricBox& box, double resolution, int stride,
                                     int64_t window);

// Boxes of whole stride blocks, north-west first, each within `max_cells` map cells, that
// together cover the cells the server reads for `box` (its half-open cells, widened to the
// stride grid); {box} when it fits, or when it would take more than kMaxRegionPieces pieces.
std::vector<MetricBox> SplitRegion(const MetricBox& box, double resolution, int stride,
                                   uint64_t max_cells);

// One raster from pieces of one stride, resolution and layer list that tile a box of cells (the
// answers to SplitRegion's boxes): equal, value for value, to the answer for the whole box.
// InvalidArgument when they do not fit together.
Result<Raster> StitchRasters(const std::vector<Raster>& pieces);

}  // namespace bgkmap
