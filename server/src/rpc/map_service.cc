#include "rpc/map_service.h"

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"

namespace bgkmap {
namespace {

// Streaming calls refused before their handler runs: finish at once with the status.
template <typename Request, typename Response>
class RefusedBidi final : public grpc::ServerBidiReactor<Request, Response> {
 public:
  explicit RefusedBidi(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

template <typename Response>
class RefusedWrite final : public grpc::ServerWriteReactor<Response> {
 public:
  explicit RefusedWrite(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

template <typename Request>
class RefusedRead final : public grpc::ServerReadReactor<Request> {
 public:
  explicit RefusedRead(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

grpc::ServerUnaryReactor* RefusedUnary(grpc::CallbackServerContext* call,
                                       const grpc::Status& status) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  reactor->Finish(status);
  return reactor;
}

// UNIMPLEMENTED, before the request is looked at, for a call the map does not offer
// (MapWrites::Offers; today both maps, a single server and a cluster node, offer every call).
grpc::Status Offered(const ServiceContext& ctx, MapWrites::Operation operation) {
  return ToGrpcStatus(ctx.map.Offers(operation));
}

}  // namespace

grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>* MapService::Ingest(
    grpc::CallbackServerContext* call) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "Ingest", &who); !s.ok()) {
    return new RefusedBidi<v1::Scan, v1::ScanAck>(s);
  }
  return StartIngestStream(ctx_, call, std::move(who));
}

grpc::ServerUnaryReactor* MapService::IngestScan(grpc::CallbackServerContext* call,
                                                 const v1::Scan* request, v1::ScanAck* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "IngestScan", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartIngestScan(ctx_, call, std::move(who), request, response);
}

grpc::ServerWriteReactor<v1::RegionChunk>* MapService::QueryRegion(
    grpc::CallbackServerContext* call, const v1::RegionRequest* request) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "QueryRegion", &who); !s.ok()) {
    return new RefusedWrite<v1::RegionChunk>(s);
  }
  return StartQueryRegion(ctx_, call, std::move(who), request);
}

grpc::ServerUnaryReactor* MapService::QueryPoints(grpc::CallbackServerContext* call,
                                                  const v1::PointsRequest* request,
                                                  v1::PointsResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "QueryPoints", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartQueryPoints(ctx_, call, std::move(who), request, response);
}

grpc::ServerUnaryReactor* MapService::CheckPath(grpc::CallbackServerContext* call,
                                                const v1::PathCheckRequest* request,
                                                v1::PathCheckResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "CheckPath", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartCheckPath(ctx_, call, std::move(who), request, response);
}

grpc::ServerWriteReactor<v1::TileUpdate>* MapService::Watch(grpc::CallbackServerContext* call,
                                                            const v1::WatchRequest* request) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "Watch", &who); !s.ok()) {
    return new RefusedWrite<v1::TileUpdate>(s);
  }
  return StartWatch(ctx_, call, std::move(who), request);
}

grpc::ServerUnaryReactor* MapService::Info(grpc::CallbackServerContext* call,
                                           const v1::InfoRequest* /*request*/,
                                           v1::InfoResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "Info", &who); !s.ok()) return RefusedUnary(call, s);
  return StartInfo(ctx_, call, std::move(who), response);
}

grpc::ServerUnaryReactor* MapService::ClearRegion(grpc::CallbackServerContext* call,
                                                  const v1::ClearRegionRequest* request,
                                                  v1::ClearRegionResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "ClearRegion", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartClearRegion(ctx_, call, std::move(who), request, response);
}

grpc::ServerWriteReactor<v1::ArchiveChunk>* MapService::ExportMap(
    grpc::CallbackServerContext* call, const v1::ExportRequest* request) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "ExportMap", &who); !s.ok()) {
    return new RefusedWrite<v1::ArchiveChunk>(s);
  }
  if (grpc::Status s = Offered(ctx_, MapWrites::Operation::kExportMap); !s.ok()) {
    return new RefusedWrite<v1::ArchiveChunk>(s);
  }
  return StartExportMap(ctx_, call, std::move(who), request);
}

grpc::ServerReadReactor<v1::ArchiveChunk>* MapService::ImportMap(grpc::CallbackServerContext* call,
                                                                 v1::ImportResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "ImportMap", &who); !s.ok()) {
    return new RefusedRead<v1::ArchiveChunk>(s);
  }
  return StartImportMap(ctx_, call, std::move(who), response);
}

grpc::ServerUnaryReactor* MapService::CorrectPoses(grpc::CallbackServerContext* call,
                                                   const grpc::ByteBuffer* request,
                                                   grpc::ByteBuffer* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "CorrectPoses", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  if (grpc::Status s = Offered(ctx_, MapWrites::Operation::kCorrectPoses); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartCorrectPoses(ctx_, call, std::move(who), request, response);
}

grpc::ServerUnaryReactor* MapService::RemoveScans(grpc::CallbackServerContext* call,
                                                  const v1::RemoveScansRequest* request,
                                                  v1::RemoveScansResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "RemoveScans", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  if (grpc::Status s = Offered(ctx_, MapWrites::Operation::kRemoveScans); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartRemoveScans(ctx_, call, std::move(who), request, response);
}

grpc::ServerUnaryReactor* MapService::RetireRobot(grpc::CallbackServerContext* call,
                                                  const v1::RetireRobotRequest* request,
                                                  v1::RetireRobotResponse* response) {
  PrincipalRef who;
  if (grpc::Status s = access_.Admit(*call, "RetireRobot", &who); !s.ok()) {
    return RefusedUnary(call, s);
  }
  if (grpc::Status s = Offered(ctx_, MapWrites::Operation::kRetireRobot); !s.ok()) {
    return RefusedUnary(call, s);
  }
  return StartRetireRobot(ctx_, call, std::move(who), request, response);
}

}  // namespace bgkmap
