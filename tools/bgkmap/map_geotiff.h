// The GeoTIFF of a map built in this process (`bgkmap build`), written strip by strip: strips of
// whole GeoTIFF block rows are extracted on several threads while the strips before them are
// compressed and written, so the output neither waits on one thread's extraction nor holds the
// whole raster in memory (on a long drive the raster of the map's box outweighs its scans).
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/geotiff.h"

namespace bgkmap::cli {

// Writes `layers` of `map` over `box` (stride 1) to the GeoTIFF `path`, with extraction on up to
// `threads` threads (and at most 256 MiB of strips extracted ahead): pixel for pixel the file
// WriteGeoTiff(ExtractRaster(map, box, layers)) writes (a pixel at stride 1 is its own cell's
// estimate). The errors of io::GeoTiffWriter.
Status WriteMapGeoTiff(const TerrainMap& map, const CellBox& box, const std::vector<Layer>& layers,
                       const std::string& path, const io::GeoTiffOptions& tiff, int threads);

}  // namespace bgkmap::cli
