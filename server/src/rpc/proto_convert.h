// The server's side of the protocol: engine Status values as gRPC statuses, and request fields
// checked into engine values. The message conversions themselves are the shared codec.
#pragma once

#include <grpcpp/support/status.h>

#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/status.h"
#include "bgkmap/proto/codec.h"
#include "bgkmap/v1/admin.pb.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/query.pb.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

grpc::Status ToGrpcStatus(const Status& status);

// Fails (INVALID_ARGUMENT naming `field`) on LAYER_UNSPECIFIED, an unknown value or a layer
// listed twice (so at most kLayerCount layers come out). An empty list means every layer.
grpc::Status LayersFromProto(const google::protobuf::RepeatedField<int>& layers,
                             const std::string& field, std::vector<Layer>* out);

}  // namespace bgkmap
