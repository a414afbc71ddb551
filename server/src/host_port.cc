#include "bgkmap/server/host_port.h"

namespace bgkmap {

Result<HostPort> ParseHostPort(std::string_view address) {
  std::string shown = "'";  // built by appending: GCC 12 misreports "'" + std::string(...)
  shown.append(address);
  shown += '\'';
  const size_t colon = address.rfind(':');
  if (colon == std::string_view::npos) {
    return Status::InvalidArgument(shown + " is not host:port");
  }
  std::string_view host = address.substr(0, colon);
  const std::string_view port = address.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  } else if (host.find(':') != std::string_view::npos) {
    return Status::InvalidArgument(shown + " is not host:port (write an IPv6 host as [addr])");
  }
  if (host.empty()) return Status::InvalidArgument(shown + " has no host");
  for (char c : host) {
    if (c == '[' || c == ']' || c == '/' || static_cast<unsigned char>(c) <= ' ') {
      return Status::InvalidArgument(shown + " is not host:port");
    }
  }
  if (port.empty() || port.size() > 5) {
    return Status::InvalidArgument(shown + ": the port must be a number in 0..65535");
  }
  uint32_t value = 0;
  for (char c : port) {
    if (c < '0' || c > '9') {
      return Status::InvalidArgument(shown + ": the port must be a number in 0..65535");
    }
    value = value * 10 + static_cast<uint32_t>(c - '0');
  }
  if (value > 65535) {
    return Status::InvalidArgument(shown + ": the port must be a number in 0..65535");
  }
  return HostPort{std::string(host), static_cast<uint16_t>(value)};
}

}  // namespace bgkmap
