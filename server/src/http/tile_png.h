// Slippy-map tiles of the live web map (docs/webmap.md): which cells a tile {z, x, y} covers,
// and its picture as a PNG.
//
// Coordinates are map-local metres (Leaflet's L.CRS.Simple scaled by 1 / resolution, y up).
// At zoom 0 one pixel is one map cell; at zoom -k a pixel is a 2^k x 2^k block of cells,
// aggregated by the region query's stride rule; at zoom +k a cell is 2^k x 2^k pixels. A tile is
// 256 x 256 pixels; tile (x, y) at zoom z has its north-west corner at pixel (256 x, 256 y), rows
// counted southwards, so tile y = 0 lies just north of map y = 0.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

inline constexpr int kWebTilePixels = 256;
inline constexpr int kWebMaxZoom = 4;  // 16 x 16 pixels per cell

// The layers a tile can show, under core's names (LayerName), in the order map.json lists them:
// what a planner gets from a region query, drawn (webmap.md). A tile reads its one layer.
inline constexpr Layer kWebLayers[] = {Layer::kElevation,
                                       Layer::kTraversability,
                                       Layer::kElevationVariance,
                                       Layer::kTraversabilityVariance,
                                       Layer::kState,
                                       Layer::kBlockReason,
                                       Layer::kDisagreement};
// One of kWebLayers by its name; InvalidArgument naming the name and the choices otherwise.
Result<Layer> ParseWebLayer(std::string_view name);

// The cells behind tile (z, x, y), with a border of one raster pixel on every side (hillshade
// needs the neighbours of the edge pixels, so tiles join without seams).
struct WebTileCells {
  CellBox box;     // cells read, border included; aligned to `stride`
  int stride = 1;  // cells per raster pixel edge (zoom <= 0)
  int scale = 1;   // tile pixels per raster pixel edge (zoom > 0)
};

// The coarsest zoom whose tiles stay within `max_region_cells` (the region query's limit).
int WebMinZoom(uint64_t max_region_cells);

// The cells of tile (z, x, y). OutOfRange if the zoom is outside [min_zoom, kWebMaxZoom] or the
// tile reaches beyond `max_coordinate` metres.
Result<WebTileCells> TileCells(int z, int64_t x, int64_t y, int min_zoom, double resolution,
                               double max_coordinate);

// The tile's picture, 256 x 256 RGBA (unknown cells transparent), from `raster` read over
// `cells.box` at `cells.stride` with the one layer `layer`.
std::vector<uint8_t> RenderTile(const Raster& raster, Layer layer, const WebTileCells& cells);

// A PNG (8-bit RGBA, fast compression) of `rgba`, width x height, rows top first.
std::string EncodePng(const std::vector<uint8_t>& rgba, int width, int height);

}  // namespace bgkmap
