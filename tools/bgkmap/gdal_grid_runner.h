// Runs GDAL's `gdal_grid` program (the peer the paper's Fig. 1 protocol is compared against) on
// a CSV of points and reads its raster back.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::cli {

struct GridExtent {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // metres
  int cols = 0, rows = 0;
};

struct SampledGrid {
  std::array<double, 6> geotransform{};
  int cols = 0, rows = 0;
  std::vector<float> values;  // NaN = no data
  double seconds = 0;         // wall time of the gdal_grid process

  // Value of the pixel containing (x, y); NaN outside or where there is no data.
  float At(double x, double y) const;
};

// Writes `csv` (header x,y,z) and a VRT beside it so gdal_grid can read the points.
Status WritePointsCsv(const std::string& csv, const std::vector<std::array<double, 3>>& points);

// `algorithm` is gdal_grid's -a value, e.g. "invdist:power=2.0". Runs gdal_grid from PATH. Cells
// gdal_grid leaves empty (no point within an invdistnn radius) are NaN: gdal_grid writes its
// `nodata` option there (default 0, and no NoData tag), so a sentinel is passed and mapped back.
Result<SampledGrid> RunGdalGrid(const std::string& csv, const std::string& algorithm,
                                const GridExtent& extent, const std::string& out_tif);

}  // namespace bgkmap::cli
