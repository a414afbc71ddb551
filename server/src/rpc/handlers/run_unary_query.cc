#include <boost/asio/post.hpp>
#include <memory>

#include "rpc/handlers/handlers.h"

namespace bgkmap {

grpc::ServerUnaryReactor* RunUnaryQuery(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                        std::function<grpc::Status()> work) {
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  auto permit = std::make_shared<Permit>(ctx.queries, ctx.limits.max_concurrent_queries);
  if (!*permit) {
    reactor->Finish(
        {grpc::StatusCode::RESOURCE_EXHAUSTED,
         "server.max_concurrent_queries = " + std::to_string(ctx.limits.max_concurrent_queries) +
             " queries are already running; retry later"});
    return reactor;
  }
  boost::asio::post(ctx.query_pool, [reactor, permit, work = std::move(work)] {
    grpc::Status status = work();
    reactor->Finish(std::move(status));
  });
  return reactor;
}

}  // namespace bgkmap
