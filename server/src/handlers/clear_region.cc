// ClearRegion (admin): forgets every cell of a box. Ordered with scans as a barrier.
#include <spdlog/spdlog.h>

#include "handlers/handlers.h"
#include "proto_convert.h"
#include "request_checks.h"

namespace bgkmap {

grpc::ServerUnaryReactor* StartClearRegion(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           const v1::ClearRegionRequest* request,
                                           v1::ClearRegionResponse* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (ctx.sessions.draining()) {
    reactor->Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
    return reactor;
  }
  CellBox box;
  if (grpc::Status s = RegionCells(request->box(), "box", ctx.store.geometry(), 1, ctx.limits,
                                   /*limit_cells=*/false, &box);
      !s.ok()) {
    reactor->Finish(s);
    return reactor;
  }
  ctx.scheduler.SubmitClear(
      box, [reactor, response, box](uint64_t version, std::vector<TileKey> changed, Status status) {
        if (!status.ok()) {
          spdlog::error("event=clear_not_persisted version={} reason=\"{}\"", version,
                        status.message());
          reactor->Finish({grpc::StatusCode::UNAVAILABLE,
                           "region not cleared: cannot persist the change: " + status.message()});
          return;
        }
        spdlog::info("event=clear_region cells=[{},{}]..[{},{}] version={} tiles={}", box.min.x,
                     box.min.y, box.max.x, box.max.y, version, changed.size());
        for (TileKey k : changed) ToProto(k, response->add_changed_tiles());
        response->set_map_version(version);
        reactor->Finish(grpc::Status::OK);
      });
  return reactor;
}

}  // namespace bgkmap
