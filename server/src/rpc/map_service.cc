#include "rpc/map_service.h"

#include "rpc/handlers/handlers.h"

namespace bgkmap {

grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>* MapService::Ingest(
    grpc::CallbackServerContext* call) {
  return StartIngestStream(ctx_, call);
}

grpc::ServerUnaryReactor* MapService::IngestScan(grpc::CallbackServerContext* call,
                                                 const v1::Scan* request, v1::ScanAck* response) {
  return StartIngestScan(ctx_, call, request, response);
}

grpc::ServerWriteReactor<v1::RegionChunk>* MapService::QueryRegion(
    grpc::CallbackServerContext* call, const v1::RegionRequest* request) {
  return StartQueryRegion(ctx_, call, request);
}

grpc::ServerUnaryReactor* MapService::QueryPoints(grpc::CallbackServerContext* call,
                                                  const v1::PointsRequest* request,
                                                  v1::PointsResponse* response) {
  return StartQueryPoints(ctx_, call, request, response);
}

grpc::ServerUnaryReactor* MapService::CheckPath(grpc::CallbackServerContext* call,
                                                const v1::PathCheckRequest* request,
                                                v1::PathCheckResponse* response) {
  return StartCheckPath(ctx_, call, request, response);
}

grpc::ServerWriteReactor<v1::TileUpdate>* MapService::Watch(grpc::CallbackServerContext* call,
                                                            const v1::WatchRequest* request) {
  return StartWatch(ctx_, call, request);
}

grpc::ServerUnaryReactor* MapService::Info(grpc::CallbackServerContext* call,
                                           const v1::InfoRequest* /*request*/,
                                           v1::InfoResponse* response) {
  return StartInfo(ctx_, call, response);
}

grpc::ServerUnaryReactor* MapService::ClearRegion(grpc::CallbackServerContext* call,
                                                  const v1::ClearRegionRequest* request,
                                                  v1::ClearRegionResponse* response) {
  return StartClearRegion(ctx_, call, request, response);
}

grpc::ServerWriteReactor<v1::ArchiveChunk>* MapService::ExportMap(
    grpc::CallbackServerContext* call, const v1::ExportRequest* request) {
  return StartExportMap(ctx_, call, request);
}

grpc::ServerReadReactor<v1::ArchiveChunk>* MapService::ImportMap(grpc::CallbackServerContext* call,
                                                                 v1::ImportResponse* response) {
  return StartImportMap(ctx_, call, response);
}

grpc::ServerUnaryReactor* MapService::RetireRobot(grpc::CallbackServerContext* call,
                                                  const v1::RetireRobotRequest* request,
                                                  v1::RetireRobotResponse* response) {
  return StartRetireRobot(ctx_, call, request, response);
}

}  // namespace bgkmap
