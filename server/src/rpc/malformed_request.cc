#include "rpc/malformed_request.h"

#include <google/protobuf/descriptor.h>

namespace bgkmap {
namespace {

class MalformedRequestInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit MalformedRequestInterceptor(const std::string& request_type)
      : request_type_(request_type) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status status = methods->GetSendStatus();
      if (status.error_code() == grpc::StatusCode::UNIMPLEMENTED &&
          status.error_message().empty()) {
        methods->ModifySendStatus(
            grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                         "request: not a valid " + request_type_ +
                             " message (the bytes do not parse as protobuf); nothing was done"));
      }
    }
    methods->Proceed();
  }

 private:
  const std::string& request_type_;  // owned by the factory, which outlives the server
};

}  // namespace

MalformedRequestInterceptorFactory::MalformedRequestInterceptorFactory() {
  const google::protobuf::ServiceDescriptor* service =
      google::protobuf::DescriptorPool::generated_pool()->FindServiceByName("bgkmap.v1.MapService");
  if (service == nullptr) return;
  for (int i = 0; i < service->method_count(); ++i) {
    const google::protobuf::MethodDescriptor* m = service->method(i);
    request_types_.emplace("/" + service->full_name() + "/" + m->name(),
                           m->input_type()->full_name());
  }
}

grpc::experimental::Interceptor* MalformedRequestInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  const char* method = info->method();
  if (method == nullptr) return nullptr;
  const auto it = request_types_.find(method);
  if (it == request_types_.end()) return nullptr;
  return new MalformedRequestInterceptor(it->second);
}

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
MapServiceInterceptors() {
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> out;
  out.push_back(std::make_unique<MalformedRequestInterceptorFactory>());
  return out;
}

}  // namespace bgkmap
