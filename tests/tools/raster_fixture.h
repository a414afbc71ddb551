// Hand-built rasters for the writer tests (independent of the engine's ExtractRaster).
#pragma once

#include <cmath>
#include <cstring>
#include <limits>

#include "bgkmap/core/raster.h"

namespace bgkmap::io::testing {

// A cols x rows raster: a tilted, bumpy elevation surface, traversability rising west to east,
// a state layer derived from it, and unknown (NaN) cells in the north-west corner and along
// one row in every layer.
inline Raster MakeTestRaster(int64_t cols, int64_t rows, double resolution = 0.25) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Raster r;
  r.stride = 2;
  r.cols = cols;
  r.rows = rows;
  r.resolution = resolution;
  r.box = {{-20, 40}, {static_cast<int>(-20 + 2 * cols - 1), static_cast<int>(40 + 2 * rows - 1)}};
  r.x0 = r.box.min.x * resolution / 2;
  r.y1 = (r.box.max.y + 1) * resolution / 2;
  r.layers = {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability, Layer::kState};
  r.data.assign(r.layers.size(), std::vector<float>(cols * rows));
  for (int64_t row = 0; row < rows; ++row) {
    for (int64_t col = 0; col < cols; ++col) {
      const size_t i = row * cols + col;
      const bool unknown = (row < rows / 4 && col < cols / 4) || row == rows / 2;
      const float t = static_cast<float>(col) / std::max<int64_t>(1, cols - 1);
      r.data[0][i] = unknown ? nan
                             : static_cast<float>(100.0 + 0.05 * col - 0.02 * row +
                                                  0.8 * std::sin(col * 0.3) * std::cos(row * 0.2));
      r.data[1][i] = unknown ? nan : 0.001f * (1 + row % 5);
      r.data[2][i] = unknown ? nan : t;
      r.data[3][i] = unknown ? 0.0f : (t < 0.5f ? 1.0f : 2.0f);
    }
  }
  return r;
}

// Every layer's values the same bits (NaN equals NaN, -0 differs from 0).
inline bool SameData(const Raster& a, const Raster& b) {
  if (a.data.size() != b.data.size()) return false;
  for (size_t l = 0; l < a.data.size(); ++l) {
    if (a.data[l].size() != b.data[l].size() ||
        std::memcmp(a.data[l].data(), b.data[l].data(), a.data[l].size() * sizeof(float)) != 0) {
      return false;
    }
  }
  return true;
}

}  // namespace bgkmap::io::testing
