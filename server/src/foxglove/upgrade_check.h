// Whether the Foxglove port takes a WebSocket upgrade request, decided before the handshake:
// the protocol's subprotocol offered, a token whose role may watch the map (when tokens are
// configured), a free client slot. Pure, so each refusal is tested without a socket.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "auth/token_table.h"

namespace bgkmap::foxglove {

struct UpgradeRequest {
  bool websocket_upgrade = false;  // a GET with "Upgrade: websocket"
  std::string_view protocols;      // Sec-WebSocket-Protocol, as sent
  std::string_view authorization;  // the Authorization header, as sent
  std::string_view target;         // the request target (path and query)
};

// The HTTP answer to a refused upgrade.
struct Refusal {
  int status = 400;    // 400, 401, 403 or 503
  std::string reason;  // one line, the response's body
};

// Refused, or admitted with the caller in `who` (when `who` is not null; null without tokens):
// the session keeps it to close itself when a reload revokes the token.
std::optional<Refusal> CheckUpgrade(const UpgradeRequest& request, const TokenTable* tokens,
                                    size_t clients, size_t max_clients,
                                    PrincipalRef* who = nullptr);

// Whether a Sec-WebSocket-Protocol value lists foxglove.websocket.v1.
bool OffersSubprotocol(std::string_view protocols);

// The `token` parameter of a request target's query ("" if none), percent-decoded.
std::string TokenFromTarget(std::string_view target);

}  // namespace bgkmap::foxglove
