// Conversions between the bgkmap.v1 messages and engine types, and from engine Status values to
// gRPC statuses.
#pragma once

#include <grpcpp/support/status.h>

#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/status.h"
#include "bgkmap/v1/admin.pb.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/query.pb.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

grpc::Status ToGrpcStatus(const Status& status);

v1::Layer ToProto(Layer layer);
// Fails (INVALID_ARGUMENT naming `field`) on LAYER_UNSPECIFIED or an unknown value. An empty list
// means every layer.
grpc::Status LayersFromProto(const google::protobuf::RepeatedField<int>& layers,
                             const std::string& field, std::vector<Layer>* out);

void ToProto(TileKey key, v1::TileKey* out);
void ToProto(const CellBox& box, v1::CellBox* out);
void ToProto(const ScanPointCounts& counts, v1::PointCounts* out);
void ToProto(const MapParams& params, v1::MapParameters* out);

// Appends rows [row_begin, row_end) of every layer of `raster` to `out` as packed float32.
void AppendRows(const Raster& raster, int64_t row_begin, int64_t row_end,
                google::protobuf::RepeatedPtrField<v1::LayerValues>* out);

// Little-endian float32 packing (the host is little-endian; checked at compile time).
std::string PackFloats(const float* values, size_t count);

}  // namespace bgkmap
