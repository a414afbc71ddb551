#include "rpc/proto_convert.h"

namespace bgkmap {

grpc::Status ToGrpcStatus(const Status& status) {
  switch (status.code()) {
    case Status::Code::kOk:
      return grpc::Status::OK;
    case Status::Code::kInvalidArgument:
      return {grpc::StatusCode::INVALID_ARGUMENT, status.message()};
    case Status::Code::kOutOfRange:
      return {grpc::StatusCode::OUT_OF_RANGE, status.message()};
    case Status::Code::kFailedPrecondition:
      return {grpc::StatusCode::FAILED_PRECONDITION, status.message()};
    case Status::Code::kDataLoss:
      return {grpc::StatusCode::DATA_LOSS, status.message()};
    case Status::Code::kIoError:
      return {grpc::StatusCode::INTERNAL, status.message()};
    case Status::Code::kUnavailable:
      return {grpc::StatusCode::UNAVAILABLE, status.message()};
    case Status::Code::kUnimplemented:
      return {grpc::StatusCode::UNIMPLEMENTED, status.message()};
  }
  return {grpc::StatusCode::UNKNOWN, status.message()};
}

grpc::Status LayersFromProto(const google::protobuf::RepeatedField<int>& layers,
                             const std::string& field, std::vector<Layer>* out) {
  // A layer listed twice would only multiply the answer (a request of a few kB could ask for
  // gigabytes): refused before anything else is looked at, so at most kLayerCount remain.
  if (layers.size() > kLayerCount) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            field + ": " + std::to_string(layers.size()) + " layers listed, but there are only " +
                std::to_string(kLayerCount) + " and each may be listed once"};
  }
  if (grpc::Status s = ToGrpcStatus(LayerListFromProto(layers, field, out)); !s.ok()) return s;
  for (size_t i = 0; i < out->size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if ((*out)[i] == (*out)[j]) {
        return {grpc::StatusCode::INVALID_ARGUMENT,
                field + "[" + std::to_string(i) + "]: layer " +
                    std::to_string(layers.Get(static_cast<int>(i))) + " is already listed at " +
                    field + "[" + std::to_string(j) + "]; each layer may be listed once"};
      }
    }
  }
  return grpc::Status::OK;
}

}  // namespace bgkmap
