// Rasters <-> bgkmap.v1 messages: packed float32 layer values, the region header, and the raster
// of a watched tile.
#pragma once

#include <google/protobuf/repeated_ptr_field.h>

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/v1/admin.pb.h"
#include "bgkmap/v1/query.pb.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

// Little-endian float32 packing (the host is little-endian; checked at compile time).
std::string PackFloats(const float* values, size_t count);
// Copies packed float32 values into `out` (resized to the value count); false on a bad length.
bool UnpackFloats(const std::string& bytes, std::vector<float>* out);

// Appends rows [row_begin, row_end) of every layer of `raster` to `out` as packed float32.
void AppendRows(const Raster& raster, int64_t row_begin, int64_t row_end,
                google::protobuf::RepeatedPtrField<v1::LayerValues>* out);
// The inverse: copies `row_count` rows of every layer from `in` into `raster` (sized by
// FromProto(RasterHeader)) from row `row_begin` on. False if the layers, the rows or a layer's
// byte count do not match the raster.
bool CopyRows(const google::protobuf::RepeatedPtrField<v1::LayerValues>& in, int64_t row_begin,
              int64_t row_count, Raster* raster);

// The raster's geometry and layers (the caller sets map_version).
void ToProto(const Raster& raster, v1::RasterHeader* out);
// The geometry and layers a header describes, without pixels (no layer arrays): a delta's.
Raster GeometryFromProto(const v1::RasterHeader& header);
// The raster a header describes, every layer sized rows * cols and zeroed for CopyRows.
Raster FromProto(const v1::RasterHeader& header);

// The raster of a watched tile: its cells at stride 1, with every layer unpacked (a layer of a
// bad length comes out empty).
Raster TileRasterFromProto(const v1::TileUpdate& update);

}  // namespace bgkmap
