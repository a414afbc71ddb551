// MapService wiring: each call is admitted by AccessControl (token and role), then served by its
// RPC's handler (rpc/handlers/).
#pragma once

#include "bgkmap/v1/map_service.grpc.pb.h"
#include "rpc/access_control.h"
#include "rpc/service_context.h"

namespace bgkmap {

// CorrectPoses is a raw method (its request's size is judged before it is parsed: issue 25).
class MapService final
    : public v1::MapService::WithRawCallbackMethod_CorrectPoses<v1::MapService::CallbackService> {
 public:
  // `tokens` null: no authentication (every caller may do everything).
  MapService(ServiceContext& ctx, const TokenTable* tokens) : ctx_(ctx), access_(tokens) {}

  grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>* Ingest(
      grpc::CallbackServerContext* call) override;
  grpc::ServerUnaryReactor* IngestScan(grpc::CallbackServerContext* call, const v1::Scan* request,
                                       v1::ScanAck* response) override;
  grpc::ServerWriteReactor<v1::RegionChunk>* QueryRegion(grpc::CallbackServerContext* call,
                                                         const v1::RegionRequest* request) override;
  grpc::ServerUnaryReactor* QueryPoints(grpc::CallbackServerContext* call,
                                        const v1::PointsRequest* request,
                                        v1::PointsResponse* response) override;
  grpc::ServerUnaryReactor* CheckPath(grpc::CallbackServerContext* call,
                                      const v1::PathCheckRequest* request,
                                      v1::PathCheckResponse* response) override;
  grpc::ServerWriteReactor<v1::TileUpdate>* Watch(grpc::CallbackServerContext* call,
                                                  const v1::WatchRequest* request) override;
  grpc::ServerUnaryReactor* Info(grpc::CallbackServerContext* call, const v1::InfoRequest* request,
                                 v1::InfoResponse* response) override;
  grpc::ServerUnaryReactor* ClearRegion(grpc::CallbackServerContext* call,
                                        const v1::ClearRegionRequest* request,
                                        v1::ClearRegionResponse* response) override;
  grpc::ServerWriteReactor<v1::ArchiveChunk>* ExportMap(grpc::CallbackServerContext* call,
                                                        const v1::ExportRequest* request) override;
  grpc::ServerReadReactor<v1::ArchiveChunk>* ImportMap(grpc::CallbackServerContext* call,
                                                       v1::ImportResponse* response) override;
  grpc::ServerUnaryReactor* CorrectPoses(grpc::CallbackServerContext* call,
                                         const grpc::ByteBuffer* request,
                                         grpc::ByteBuffer* response) override;
  grpc::ServerUnaryReactor* RemoveScans(grpc::CallbackServerContext* call,
                                        const v1::RemoveScansRequest* request,
                                        v1::RemoveScansResponse* response) override;
  grpc::ServerUnaryReactor* RetireRobot(grpc::CallbackServerContext* call,
                                        const v1::RetireRobotRequest* request,
                                        v1::RetireRobotResponse* response) override;

 private:
  ServiceContext& ctx_;
  const AccessControl access_;
};

}  // namespace bgkmap
