// ESRI ASCII grid (.asc) reader: a header of ncols, nrows, xllcorner|xllcenter,
// yllcorner|yllcenter, cellsize and optional NODATA_value, then nrows rows north to south.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct EsriAsciiGrid {
  int64_t cols = 0;
  int64_t rows = 0;
  double x0 = 0;  // west edge of column 0, metres
  double y0 = 0;  // south edge of the last row, metres
  double cellsize = 0;
  std::vector<float> values;  // rows * cols, row 0 = north; NaN where NODATA

  // Value of the cell containing (x, y), NaN outside the grid.
  float At(double x, double y) const;
};

// One DataLoss line naming the file on a malformed header or a short / non-numeric body.
Result<EsriAsciiGrid> ReadEsriAsciiGrid(const std::string& path);

}  // namespace bgkmap::io
