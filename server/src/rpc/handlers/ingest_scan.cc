// IngestScan: one scan, one ack. Rejections fail the call with the reason's status code.
#include <boost/asio/post.hpp>
#include <memory>

#include "rpc/handlers/handlers.h"
#include "rpc/handlers/ingest_pipeline.h"

namespace bgkmap {

grpc::ServerUnaryReactor* StartIngestScan(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                          PrincipalRef who, const v1::Scan* request,
                                          v1::ScanAck* response) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  if (ctx.sessions.draining()) {
    reactor->Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down: scan not applied"});
    return reactor;
  }
  auto permit = std::make_shared<Permit>(ctx.unary_scans, ctx.limits.max_inflight_unary_scans);
  if (!*permit) {
    reactor->Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
                     "server.max_inflight_unary_scans = " +
                         std::to_string(ctx.limits.max_inflight_unary_scans) +
                         " scans are already in flight; retry later or use the Ingest stream"});
    return reactor;
  }
  boost::asio::post(ctx.ingest_pool, [&ctx, who, request, response, reactor, permit] {
    IngestScanMessage(ctx, *who, *request,
                      [response, reactor, permit](v1::ScanAck ack, grpc::Status status) {
                        *response = std::move(ack);
                        reactor->Finish(status);
                      });
  });
  return reactor;
}

}  // namespace bgkmap
