// A request message that does not parse: gRPC's callback API answers it UNIMPLEMENTED with an
// empty message, before any handler sees the call, which tells the client nothing and looks like
// a missing method. This server interceptor rewrites exactly that answer, for the methods of
// bgkmap.v1.MapService (none of whose handlers ever answers UNIMPLEMENTED), into
// INVALID_ARGUMENT naming the message type.
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace bgkmap {

class MalformedRequestInterceptorFactory final
    : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  MalformedRequestInterceptorFactory();
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;

 private:
  // "/bgkmap.v1.MapService/QueryPoints" -> "bgkmap.v1.PointsRequest"
  std::unordered_map<std::string, std::string> request_types_;
};

// The interceptor factories bgkmapd installs.
std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
MapServiceInterceptors();

}  // namespace bgkmap
