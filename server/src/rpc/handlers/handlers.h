// One handler per MapService RPC. Each returns the reactor that serves one call; heavy work runs
// on the context's worker pools, never on gRPC's own threads. `who` is the caller, already
// allowed the RPC's right (rpc/access_control.h); handlers check what depends on the request (a
// robot token's ids) and count the token's quotas.
#pragma once

#include <grpcpp/support/server_callback.h>

#include <chrono>
#include <functional>
#include <optional>

#include "bgkmap/v1/map_service.grpc.pb.h"
#include "rpc/service_context.h"

namespace bgkmap {

grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>* StartIngestStream(ServiceContext& ctx,
                                                                  grpc::CallbackServerContext* call,
                                                                  PrincipalRef who);
grpc::ServerUnaryReactor* StartIngestScan(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                          PrincipalRef who, const v1::Scan* request,
                                          v1::ScanAck* response);
grpc::ServerWriteReactor<v1::RegionChunk>* StartQueryRegion(ServiceContext& ctx,
                                                            grpc::CallbackServerContext* call,
                                                            PrincipalRef who,
                                                            const v1::RegionRequest* request);
grpc::ServerUnaryReactor* StartQueryPoints(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::PointsRequest* request,
                                           v1::PointsResponse* response);
grpc::ServerUnaryReactor* StartCheckPath(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                         PrincipalRef who, const v1::PathCheckRequest* request,
                                         v1::PathCheckResponse* response);
grpc::ServerWriteReactor<v1::TileUpdate>* StartWatch(ServiceContext& ctx,
                                                     grpc::CallbackServerContext* call,
                                                     PrincipalRef who,
                                                     const v1::WatchRequest* request);
grpc::ServerUnaryReactor* StartInfo(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                    PrincipalRef who, v1::InfoResponse* response);
grpc::ServerUnaryReactor* StartClearRegion(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::ClearRegionRequest* request,
                                           v1::ClearRegionResponse* response);
grpc::ServerWriteReactor<v1::ArchiveChunk>* StartExportMap(ServiceContext& ctx,
                                                           grpc::CallbackServerContext* call,
                                                           PrincipalRef who,
                                                           const v1::ExportRequest* request);
grpc::ServerReadReactor<v1::ArchiveChunk>* StartImportMap(ServiceContext& ctx,
                                                          grpc::CallbackServerContext* call,
                                                          PrincipalRef who,
                                                          v1::ImportResponse* response);

// CorrectPoses is served raw: `request` is a bgkmap.v1.CorrectPosesRequest's bytes, judged by
// their size before they are parsed; `response` receives a CorrectPosesResponse's.
grpc::ServerUnaryReactor* StartCorrectPoses(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                            PrincipalRef who, const grpc::ByteBuffer* request,
                                            grpc::ByteBuffer* response);
grpc::ServerUnaryReactor* StartRemoveScans(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::RemoveScansRequest* request,
                                           v1::RemoveScansResponse* response);

grpc::ServerUnaryReactor* StartRetireRobot(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::RetireRobotRequest* request,
                                           v1::RetireRobotResponse* response);

// What a query's work checks between steps, so that no call outlives its purpose: the client
// cancelled (or the server's shutdown cancelled it), the client's deadline passed, or it ran
// longer than server.max_query_seconds.
class QueryControl {
 public:
  QueryControl(grpc::CallbackServerContext* call, double max_seconds);
  // OK, or the status to stop with (CANCELLED, DEADLINE_EXCEEDED).
  grpc::Status Check() const;

 private:
  grpc::CallbackServerContext* call_;
  std::chrono::system_clock::time_point deadline_;  // the earlier of the two
  bool server_limit_ = false;                       // deadline_ is max_query_seconds'
  double max_seconds_;
};

// Runs `work` on the query pool under the concurrent-query limit and finishes `reactor` with its
// status (RESOURCE_EXHAUSTED without running it when the limit is reached; CANCELLED or
// DEADLINE_EXCEEDED without running it when the call ended while it waited for a thread).
// A query that ran OK is timed, request to answer, as `phase`. `now`, if given, is tried first
// on the calling (gRPC) thread: a short answer that needs no wait is finished there, which saves
// waking a pool thread on a busy machine; it returns empty to leave the query to `work`.
grpc::ServerUnaryReactor* RunUnaryQuery(
    ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who, RequestPhase phase,
    std::function<grpc::Status(const QueryControl&)> work,
    const std::function<std::optional<grpc::Status>(const QueryControl&)>& now = nullptr);

}  // namespace bgkmap
