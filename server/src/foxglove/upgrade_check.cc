#include "foxglove/upgrade_check.h"

#include "auth/principal.h"
#include "foxglove/protocol.h"

namespace bgkmap::foxglove {
namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string PercentDecoded(std::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size()) {
      const int hi = HexDigit(s[i + 1]), lo = HexDigit(s[i + 2]);
      if (hi >= 0 && lo >= 0) {
        out.push_back(static_cast<char>(hi * 16 + lo));
        i += 2;
        continue;
      }
    }
    out.push_back(s[i] == '+' ? ' ' : s[i]);
  }
  return out;
}

}  // namespace

bool OffersSubprotocol(std::string_view protocols) {
  while (!protocols.empty()) {
    const size_t comma = protocols.find(',');
    if (Trim(protocols.substr(0, comma)) == kSubprotocol) return true;
    if (comma == std::string_view::npos) break;
    protocols.remove_prefix(comma + 1);
  }
  return false;
}

std::string TokenFromTarget(std::string_view target) {
  const size_t q = target.find('?');
  if (q == std::string_view::npos) return "";
  std::string_view query = target.substr(q + 1);
  while (!query.empty()) {
    const size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    if (pair.substr(0, 6) == "token=") return PercentDecoded(pair.substr(6));
    if (amp == std::string_view::npos) break;
    query.remove_prefix(amp + 1);
  }
  return "";
}

std::optional<Refusal> CheckUpgrade(const UpgradeRequest& request, const TokenTable* tokens,
                                    size_t clients, size_t max_clients, PrincipalRef* admitted) {
  if (!request.websocket_upgrade) {
    return Refusal{400, "bgkmapd's Foxglove port speaks WebSocket only (subprotocol " +
                            std::string(kSubprotocol) + "): connect Foxglove to ws://host:port"};
  }
  if (!OffersSubprotocol(request.protocols)) {
    return Refusal{400, "the upgrade must offer the WebSocket subprotocol " +
                            std::string(kSubprotocol) + " (Sec-WebSocket-Protocol)"};
  }
  PrincipalRef who;
  if (tokens != nullptr) {
    std::string authorization(request.authorization);
    if (authorization.empty()) {
      const std::string token = TokenFromTarget(request.target);
      if (!token.empty()) authorization = "Bearer " + token;
    }
    std::string why;
    who = tokens->Authenticate(authorization, &why);
    if (who == nullptr) {
      // (Authenticate's reasons speak of gRPC metadata.)
      return Refusal{401, std::string("unauthorized: ") +
                              (authorization.empty() ? "no token" : "not a valid bearer token") +
                              " (send 'Authorization: Bearer <token>' or connect to "
                              "ws://host:port/?token=<token>)"};
    }
    if (!who->Has(Right::kWatch)) {
      return Refusal{403, "forbidden: token '" + who->name + "' (role " + RoleName(who->role) +
                              ") may not watch the map; a planner or admin token may"};
    }
  }
  if (clients >= max_clients) {
    return Refusal{503, "too many Foxglove clients (server.foxglove.max_clients = " +
                            std::to_string(max_clients) + "); retry later"};
  }
  if (admitted != nullptr) *admitted = std::move(who);
  return std::nullopt;
}

}  // namespace bgkmap::foxglove
