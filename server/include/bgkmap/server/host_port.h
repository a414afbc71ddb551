// "host:port" addresses of the server's listeners (the metrics endpoint).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "bgkmap/core/status.h"

namespace bgkmap {

struct HostPort {
  std::string host;   // a name or an address; IPv6 without the brackets
  uint16_t port = 0;  // 0: any free port
};

// Splits "host:port" ("127.0.0.1:9100", "localhost:0", "[::1]:9100"). The host must not be
// empty and the port is decimal in 0..65535. The message says what is wrong with `address`
// (the caller prefixes the key).
Result<HostPort> ParseHostPort(std::string_view address);

}  // namespace bgkmap
