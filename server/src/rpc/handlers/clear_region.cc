// ClearRegion (admin): forgets every cell of a box, ordered with the scans (a single server: as
// a barrier; a cluster: in its log, and each shard clears its copies as it reads it).
#include <spdlog/spdlog.h>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {

grpc::ServerUnaryReactor* StartClearRegion(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::ClearRegionRequest* request,
                                           v1::ClearRegionResponse* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (ctx.sessions.draining()) {
    reactor->Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
    return reactor;
  }
  CellBox box;
  if (grpc::Status s = RegionCells(request->box(), "box", ctx.map.geometry(), 1, ctx.limits,
                                   /*limit_cells=*/false, &box);
      !s.ok()) {
    reactor->Finish(s);
    return reactor;
  }
  ctx.map.SubmitClear(box, [reactor, response, box, who,
                            peer = call->peer()](const ClearOutcome& outcome) {
    if (!outcome.status.ok()) {
      const Status::Code code = outcome.status.code();
      if (code != Status::Code::kIoError && code != Status::Code::kDataLoss) {
        // The map refused it (a cluster's log out of reach): its own code.
        reactor->Finish(ToGrpcStatus(outcome.status));
        return;
      }
      spdlog::error("event=clear_not_persisted version={} reason=\"{}\"", outcome.version,
                    outcome.status.message());
      reactor->Finish(
          {grpc::StatusCode::UNAVAILABLE,
           "region not cleared: cannot persist the change: " + outcome.status.message()});
      return;
    }
    spdlog::info("event=clear_region cells=[{},{}]..[{},{}] version={} tiles={}", box.min.x,
                 box.min.y, box.max.x, box.max.y, outcome.version, outcome.changed_tiles.size());
    AuditLog(*who, "clear_region",
             "box_cells=[" + std::to_string(box.min.x) + "," + std::to_string(box.min.y) + "]..[" +
                 std::to_string(box.max.x) + "," + std::to_string(box.max.y) + "]",
             outcome.version, peer);
    for (TileKey k : outcome.changed_tiles) ToProto(k, response->add_changed_tiles());
    response->set_map_version(outcome.version);
    reactor->Finish(grpc::Status::OK);
  });
  return reactor;
}

}  // namespace bgkmap
