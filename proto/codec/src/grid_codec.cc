#include "bgkmap/proto/grid_codec.h"

namespace bgkmap {

void ToProto(TileKey key, v1::TileKey* out) {
  out->set_x(key.x);
  out->set_y(key.y);
}

TileKey FromProto(const v1::TileKey& key) { return {key.x(), key.y()}; }

void ToProto(const CellBox& box, v1::CellBox* out) {
  out->set_min_x(box.min.x);
  out->set_min_y(box.min.y);
  out->set_max_x(box.max.x);
  out->set_max_y(box.max.y);
}

CellBox FromProto(const v1::CellBox& box) {
  return {{box.min_x(), box.min_y()}, {box.max_x(), box.max_y()}};
}

}  // namespace bgkmap
