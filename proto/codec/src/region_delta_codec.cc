#include "bgkmap/proto/region_delta_codec.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "bgkmap/proto/grid_codec.h"
#include "bgkmap/proto/layer_codec.h"
#include "bgkmap/proto/raster_codec.h"

namespace bgkmap {

bool IsUnknownEverywhere(const Raster& raster) {
  for (size_t i = 0; i < raster.layers.size(); ++i) {
    // Bitwise: a NaN of another payload would not come back from a tombstone.
    const uint32_t unknown = std::bit_cast<uint32_t>(UnknownValue(raster.layers[i]));
    for (float v : raster.data[i]) {
      if (std::bit_cast<uint32_t>(v) != unknown) return false;
    }
  }
  return true;
}

void ToProto(TileKey key, const CellBox& region, const Raster& part, v1::TilePatch* out) {
  ToProto(key, out->mutable_key());
  const int s = part.stride;
  out->set_row_start(static_cast<uint32_t>((region.max.y - part.box.max.y) / s));
  out->set_col_start(static_cast<uint32_t>((part.box.min.x - region.min.x) / s));
  out->set_rows(static_cast<uint32_t>(part.rows));
  out->set_cols(static_cast<uint32_t>(part.cols));
  out->clear_layers();
  if (IsUnknownEverywhere(part)) {
    out->set_tombstone(true);
    return;
  }
  out->set_tombstone(false);
  AppendRows(part, 0, part.rows, out->mutable_layers());
}

bool ApplyPatch(const v1::TilePatch& patch, Raster* region) {
  const int64_t r0 = patch.row_start(), c0 = patch.col_start();
  const int64_t rows = patch.rows(), cols = patch.cols();
  if (r0 + rows > region->rows || c0 + cols > region->cols) return false;
  const size_t n = static_cast<size_t>(rows * cols);
  if (!patch.tombstone()) {
    if (patch.layers_size() != static_cast<int>(region->layers.size())) return false;
    for (int i = 0; i < patch.layers_size(); ++i) {
      const v1::LayerValues& lv = patch.layers(i);
      if (FromProto(lv.layer()) != region->layers[i] || lv.values().size() != n * sizeof(float)) {
        return false;
      }
    }
  } else if (patch.layers_size() != 0) {
    return false;
  }
  for (size_t i = 0; i < region->layers.size(); ++i) {
    std::vector<float>& data = region->data[i];
    const float unknown = UnknownValue(region->layers[i]);
    for (int64_t r = 0; r < rows; ++r) {
      float* row = data.data() + (r0 + r) * region->cols + c0;
      if (patch.tombstone()) {
        std::fill(row, row + cols, unknown);
      } else if (cols > 0) {
        std::memcpy(row, patch.layers(static_cast<int>(i)).values().data() + r * cols * 4,
                    static_cast<size_t>(cols) * sizeof(float));
      }
    }
  }
  return true;
}

}  // namespace bgkmap
