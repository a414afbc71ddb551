#include <boost/asio/post.hpp>
#include <chrono>
#include <memory>
#include <sstream>

#include "rpc/handlers/handlers.h"

namespace bgkmap {

QueryControl::QueryControl(grpc::CallbackServerContext* call, double max_seconds)
    : call_(call), deadline_(call->deadline()), max_seconds_(max_seconds) {
  if (max_seconds > 0) {
    const auto limit = std::chrono::system_clock::now() +
                       std::chrono::duration_cast<std::chrono::system_clock::duration>(
                           std::chrono::duration<double>(max_seconds));
    if (limit < deadline_) {
      deadline_ = limit;
      server_limit_ = true;
    }
  }
}

grpc::Status QueryControl::Check() const {
  if (call_->IsCancelled()) return {grpc::StatusCode::CANCELLED, "query cancelled"};
  if (std::chrono::system_clock::now() >= deadline_) {
    if (!server_limit_) {
      return {grpc::StatusCode::DEADLINE_EXCEEDED, "the client's deadline passed; query stopped"};
    }
    std::ostringstream s;
    s << "query stopped after server.max_query_seconds = " << max_seconds_ << " s";
    return {grpc::StatusCode::DEADLINE_EXCEEDED, s.str()};
  }
  return grpc::Status::OK;
}

grpc::ServerUnaryReactor* RunUnaryQuery(
    ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who, RequestPhase phase,
    std::function<grpc::Status(const QueryControl&)> work,
    const std::function<std::optional<grpc::Status>(const QueryControl&)>& now) {
  const auto received = std::chrono::steady_clock::now();
  grpc::ServerUnaryReactor* reactor = call->DefaultReactor();
  auto permit = std::make_shared<QueryPermit>(ctx, *who);
  if (!*permit) {
    reactor->Finish(permit->refusal());
    return reactor;
  }
  auto control = std::make_shared<QueryControl>(call, ctx.limits.max_query_seconds);
  // A query that ran OK is timed; either way the call ends with its status.
  auto finish = [&ctx, reactor, phase, received](grpc::Status status) {
    if (status.ok()) ctx.latencies.of(phase).Record(std::chrono::steady_clock::now() - received);
    reactor->Finish(std::move(status));
  };
  if (now) {
    if (std::optional<grpc::Status> answered = now(*control)) {
      finish(std::move(*answered));
      return reactor;
    }
  }
  boost::asio::post(ctx.query_pool, [permit, control, finish, work = std::move(work)] {
    // A call that ended while it waited for a thread is not worked on.
    grpc::Status status = control->Check();
    if (status.ok()) status = work(*control);
    finish(std::move(status));
  });
  return reactor;
}

}  // namespace bgkmap
