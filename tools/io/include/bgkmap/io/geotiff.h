// GeoTIFF export of rasters (GDAL GTiff): one float32 band per layer, the band description
// naming the layer (LayerName), NoData = NaN on every band, north-up geotransform
// (x0, resolution, 0, y1, 0, -resolution), DEFLATE (level 3, no predictor), tiled.
// The cell box and stride are kept as BGKMAP_* metadata so ReadGeoTiff restores the Raster.
//
// Thread-safe: GDAL drivers are registered once; GDAL's own error output is silenced and its
// last error message becomes the Status.
#pragma once

#include <array>
#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct GeoTiffOptions {
  // Coordinate reference system in any form GDAL's SetFromUserInput accepts ("EPSG:32633",
  // WKT, PROJ). Empty writes none: the map frame is local unless the input was georeferenced.
  std::string spatial_reference;
  // Cloud-Optimized GeoTIFF (GDAL's COG driver): tiled, DEFLATE, with overviews picked by
  // nearest neighbour, readable by range requests; gdalinfo reports LAYOUT=COG.
  bool cloud_optimized = false;
  // Where the map frame's (0, 0, 0) sits in `spatial_reference`: [easting, northing, height].
  // Added to the geotransform's origin and to the elevation band (its variance is unchanged).
  // The BGKMAP_BOX metadata keeps the map-frame cells.
  std::array<double, 3> origin{0, 0, 0};
  // GDAL's block cache while a COG is made from its staging file (GeoTiffWriter::Finish); 0:
  // GDAL's default, 5% of the RAM, which the COG driver fills while it copies a large raster.
  // The cache is process-wide: set for the copy and restored after it.
  uint64_t cog_cache_bytes = 0;
  // Threads compressing the tiles (GDAL's NUM_THREADS). Each tile is compressed alone and the
  // tiles are written in order, so the file is the same bytes for any number.
  int threads = 1;
};

// Fails (InvalidArgument) if the raster is empty or its data does not match rows x cols x layers.
Status WriteGeoTiff(const Raster& raster, const std::string& path,
                    const GeoTiffOptions& options = {});

// Reads a GeoTIFF written by WriteGeoTiff (or any north-up float GeoTIFF whose band
// descriptions are layer names). Without BGKMAP_* metadata, stride is 1 and the box is derived
// from the geotransform in units of the pixel size.
Result<Raster> ReadGeoTiff(const std::string& path);

}  // namespace bgkmap::io
