// Outcome of a call to bgkmapd: the gRPC status code and the server's message (which names the
// offending field and the limit). Kept free of gRPC headers so users need none.
#pragma once

#include <optional>
#include <string>
#include <utility>

#include "bgkmap/core/status.h"

namespace bgkmap {

// The google.rpc.Code values.
enum class RpcCode {
  kOk = 0,
  kCancelled = 1,
  kUnknown = 2,
  kInvalidArgument = 3,
  kDeadlineExceeded = 4,
  kNotFound = 5,
  kAlreadyExists = 6,
  kPermissionDenied = 7,
  kResourceExhausted = 8,
  kFailedPrecondition = 9,
  kAborted = 10,
  kOutOfRange = 11,
  kUnimplemented = 12,
  kInternal = 13,
  kUnavailable = 14,
  kDataLoss = 15,
  kUnauthenticated = 16,
};

const char* RpcCodeName(RpcCode code);

class RpcStatus {
 public:
  RpcStatus() = default;
  RpcStatus(RpcCode code, std::string message) : code_(code), message_(std::move(message)) {}

  bool ok() const { return code_ == RpcCode::kOk; }
  RpcCode code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string ToString() const;  // "RESOURCE_EXHAUSTED: points: ..."

 private:
  RpcCode code_ = RpcCode::kOk;
  std::string message_;
};

// A value or the RpcStatus explaining why there is none.
template <typename T>
using RpcResult = Result<T, RpcStatus>;

}  // namespace bgkmap
