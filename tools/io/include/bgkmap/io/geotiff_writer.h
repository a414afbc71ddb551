// A GeoTIFF written part by part (the file format of geotiff.h), so a raster of any size goes to
// disk without ever being whole in memory: `bgkmap query` writes a region it reads in windows.
//
// The file is a tiled GTiff (blocks of kGeoTiffBlockPixels square, DEFLATE, one band per layer);
// each Write lands in its place and the blocks it completed leave memory at once (GDAL's block
// cache is flushed after every part). Parts made of whole blocks (the raster's last block column
// and row may be partial) keep the file compact: a block written twice is stored twice.
//
// A Cloud-Optimized GeoTIFF needs its overviews, which GDAL's COG driver makes only by copying a
// finished raster: the parts go to a staging GTiff beside `path` (`path` + ".staging.tif"), which
// Finish copies with overviews into `path` and deletes. Disk cost while finishing: the staging file
// (about the size of the result without overviews) plus GDAL's temporary overviews (about a
// third of it) beside the result.
#pragma once

#include <memory>
#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/io/geotiff.h"

namespace bgkmap::io {

inline constexpr int kGeoTiffBlockPixels = 256;

class GeoTiffWriter {
 public:
  // Creates `path` for a raster of `geometry` (box, stride, rows, cols, resolution, x0, y1 and
  // layers; its data is not looked at) with `options` (geotiff.h). InvalidArgument for an empty
  // or too large geometry, no layers, a non-finite origin or an unknown spatial reference;
  // IoError when GDAL cannot create the file.
  static Result<std::unique_ptr<GeoTiffWriter>> Create(const Raster& geometry,
                                                       const std::string& path,
                                                       const GeoTiffOptions& options);
  ~GeoTiffWriter();
  GeoTiffWriter(const GeoTiffWriter&) = delete;
  GeoTiffWriter& operator=(const GeoTiffWriter&) = delete;

  // Writes `part`, a raster of the same stride, resolution and layers whose box lies inside the
  // geometry's on its stride grid, at its place (the elevation shifted by the origin's height).
  // InvalidArgument when it does not fit; IoError when GDAL fails.
  Status Write(const Raster& part);

  // Closes the file (and for a COG makes it from the staging file). Parts never written read as
  // unknown (NaN). After Finish, Write fails; a writer destroyed unfinished deletes its files.
  Status Finish();

 private:
  struct Impl;
  explicit GeoTiffWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace bgkmap::io
