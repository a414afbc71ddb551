// Client-side conversions between bgkmap.v1 messages and the public client types. The engine
// types (layers, tile keys, cell boxes, parameters, rasters) go through the shared codec.
#pragma once

#include <grpcpp/support/status.h>

#include <array>
#include <span>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/proto/codec.h"
#include "bgkmap/v1/admin.pb.h"
#include "bgkmap/v1/archive.pb.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/query.pb.h"

namespace bgkmap::client_codec {

using bgkmap::FromProto;
using bgkmap::ToProto;

RpcStatus FromGrpc(const grpc::Status& status);

// Requests.
void ToProto(const MetricBox& box, v1::BoundingBox* out);
void ToProto(const ScanPose& pose, v1::Pose3* out);
void ToProto(const ScanData& scan, v1::Scan* out);
void ToProto(const RegionQuery& query, v1::RegionRequest* out);
void ToProto(std::span<const std::array<double, 2>> points, const std::vector<Layer>& layers,
             v1::PointsRequest* out);
void ToProto(const PathQuery& query, v1::PathCheckRequest* out);
void ToProto(const WatchQuery& query, v1::WatchRequest* out);

// Responses.
MetricBox FromProto(const v1::BoundingBox& box);
ScanAck FromProto(const v1::ScanAck& ack);
MapInfo FromProto(const v1::InfoResponse& info);
PointValues FromProto(const v1::PointsResponse& response);
PathCheck FromProto(const v1::PathCheckResponse& response);
TileUpdate FromProto(const v1::TileUpdate& update);
ClearResult FromProto(const v1::ClearRegionResponse& response);
ImportResult FromProto(const v1::ImportResponse& response);

}  // namespace bgkmap::client_codec
