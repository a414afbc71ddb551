// Outcome of a call to bgkmapd: the gRPC status code and the server's message (which names the
// offending field and the limit). Kept free of gRPC headers so users need none.
#pragma once

#include <optional>
#include <string>
#include <utility>

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
class RpcResult {
 public:
  RpcResult(T value) : value_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  RpcResult(RpcStatus status)
      : status_(std::move(status)) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return value_.has_value(); }
  const RpcStatus& status() const { return status_; }
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }
  T& operator*() & { return *value_; }
  const T& operator*() const& { return *value_; }

 private:
  std::optional<T> value_;
  RpcStatus status_;
};

}  // namespace bgkmap
