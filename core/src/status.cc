#include "bgkmap/core/status.h"

namespace bgkmap {

std::string Status::ToString() const {
  switch (code_) {
    case Code::kOk:
      return "OK";
    case Code::kInvalidArgument:
      return "invalid argument: " + message_;
    case Code::kOutOfRange:
      return "out of range: " + message_;
    case Code::kFailedPrecondition:
      return "failed precondition: " + message_;
    case Code::kDataLoss:
      return "data loss: " + message_;
    case Code::kIoError:
      return "I/O error: " + message_;
    case Code::kUnavailable:
      return "unavailable: " + message_;
    case Code::kUnimplemented:
      return "unimplemented: " + message_;
  }
  return message_;
}

}  // namespace bgkmap
