// A maximum mipmap over a grid of height bounds: level k holds the maximum of 2^k x 2^k cells of
// level 0, so the maximum over any cell rectangle is the maximum of at most 4 cells of one level.
// Heightfield ray casting uses it to skip the spans of a ray that pass above all terrain.
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap::sim {

class MaxMipmap {
 public:
  MaxMipmap() = default;
  // values[r * cols + c]; -inf marks a cell with nothing in it.
  MaxMipmap(int64_t cols, int64_t rows, std::vector<float> values);

  int64_t cols() const { return cols_.empty() ? 0 : cols_[0]; }
  int64_t rows() const { return rows_.empty() ? 0 : rows_[0]; }

  // An upper bound of the maximum over columns c0..c1 and rows r0..r1 (inclusive, clamped to
  // the grid; -inf if the rectangle misses the grid). Exact when the rectangle is one cell.
  float Max(int64_t c0, int64_t r0, int64_t c1, int64_t r1) const;

 private:
  std::vector<int64_t> cols_, rows_;
  std::vector<std::vector<float>> levels_;
};

}  // namespace bgkmap::sim
