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
  }
  return {grpc::StatusCode::UNKNOWN, status.message()};
}

grpc::Status LayersFromProto(const google::protobuf::RepeatedField<int>& layers,
                             const std::string& field, std::vector<Layer>* out) {
  return ToGrpcStatus(LayerListFromProto(layers, field, out));
}

}  // namespace bgkmap
