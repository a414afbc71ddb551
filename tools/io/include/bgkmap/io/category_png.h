// A categorical map as a PNG, for figures that explain (docs/results.md, "Real drives"): one
// class per cell, one colour per class, north up, with a legend of the classes below the map.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct CategoryClass {
  std::string label;  // letters, digits and ". - : =" (the bitmap font's characters)
  std::array<uint8_t, 3> rgb;
};

// `classes[row * cols + col]` indexes `legend` (row 0 = north). Each cell becomes a `scale` x
// `scale` block. The legend lists every class with its colour swatch. Fails if a class index is
// out of range or the file cannot be written.
Status WriteCategoryPng(const std::string& path, int cols, int rows,
                        const std::vector<uint8_t>& classes,
                        const std::vector<CategoryClass>& legend, int scale = 1);

}  // namespace bgkmap::io
