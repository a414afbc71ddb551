// Client-side conversions between bgkmap.v1 messages and the public client types.
#pragma once

#include <grpcpp/support/status.h>

#include "bgkmap/client/client.h"
#include "bgkmap/v1/admin.pb.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/query.pb.h"

namespace bgkmap::client_codec {

RpcStatus FromGrpc(const grpc::Status& status);
v1::Layer ToProto(Layer layer);
Layer FromProto(v1::Layer layer);
void ToProto(const MetricBox& box, v1::BoundingBox* out);
void ToProto(const ScanData& scan, v1::Scan* out);
ScanAck FromProto(const v1::ScanAck& ack);
MapInfo FromProto(const v1::InfoResponse& info);
CellBox FromProto(const v1::CellBox& box);
// Copies packed float32 values into `out` (resized to the value count); false on a bad length.
bool UnpackFloats(const std::string& bytes, std::vector<float>* out);

}  // namespace bgkmap::client_codec
