// Dense rasters of derived layers over a box of cells: what a region query, a GeoTIFF and a
// preview image are made of.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {

// Rows run north to south (row 0 holds the largest y), columns west to east, as in a north-up
// image. With stride s > 1 each raster pixel aggregates an s x s block of cells.
struct Raster {
  CellBox box;     // cells covered (at map resolution)
  int stride = 1;  // map cells per raster pixel edge
  int64_t cols = 0;
  int64_t rows = 0;
  double resolution = 0;  // of a raster pixel, metres (= map resolution * stride)
  double x0 = 0;          // west edge, metres
  double y1 = 0;          // north edge, metres
  std::vector<Layer> layers;
  std::vector<std::vector<float>> data;  // data[i] holds layers[i], rows*cols, NaN = unknown

  const std::vector<float>* Find(Layer layer) const;
};

// The geometry of the raster of `box` at `stride` on a map of `map_resolution` (no data).
Raster RasterGeometry(double map_resolution, const CellBox& box, const std::vector<Layer>& layers,
                      int stride = 1);

// What a raster holds for an unknown pixel: NaN (quiet, 0x7fc00000), 0 in the state layer.
float UnknownValue(Layer layer);

// The cells of tile `tile` inside `region` (a region box aligned to `stride` blocks, as a region
// query widens it), widened to whole stride blocks: the part of the region raster that tile
// `tile`'s cells reach (a block that straddles tiles is in the part of each). Empty if the tile
// does not meet the region. A raster of it at `stride` has exactly the region raster's pixels
// there, bit for bit (a pixel depends on its block's cells only).
CellBox TilePatchCells(const GridGeometry& geometry, const CellBox& region, int stride,
                       TileKey tile);

// Extracts `layers` over `box` (clipped to nothing: unknown cells come out as NaN).
// Aggregation over a stride block: statistics are summed (the posterior of the union of the
// block's training data) for elevation, and the block's worst (largest) traversability,
// variance and disagreement are kept, so a coarse view never hides an obstacle; state: blocked if
// a cell is, else unknown if one was seen too little, else traversable; reasons: all the cells'.
Raster ExtractRaster(const TerrainMap& map, const CellBox& box, const std::vector<Layer>& layers,
                     int stride = 1);

}  // namespace bgkmap
