// TileKey and CellBox <-> their bgkmap.v1 messages.
#pragma once

#include "bgkmap/core/grid.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

void ToProto(TileKey key, v1::TileKey* out);
TileKey FromProto(const v1::TileKey& key);
void ToProto(const CellBox& box, v1::CellBox* out);
CellBox FromProto(const v1::CellBox& box);

}  // namespace bgkmap
