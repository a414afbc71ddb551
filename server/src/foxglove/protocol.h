// The Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1), the part bgkmapd speaks:
// the server's JSON messages (serverInfo, advertise, status), the client's (subscribe,
// unsubscribe; anything else is refused with a status naming it) and the binary message frame.
// Pure: no sockets, so every rule here is tested without one.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace bgkmap::foxglove {

inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";

struct Channel {
  uint32_t id = 0;
  std::string topic;
  std::string schema_name;    // "foxglove.Grid"
  std::string schema_base64;  // a FileDescriptorSet holding the schema, base64
};

// Status levels as the protocol numbers them.
enum class StatusLevel { kInfo = 0, kWarning = 1, kError = 2 };

std::string ServerInfoJson(std::string_view name, std::string_view session_id);
std::string AdvertiseJson(const std::vector<Channel>& channels);
std::string StatusJson(StatusLevel level, std::string_view message);

// A client's subscription: its own id for it and the channel.
struct Subscription {
  uint32_t id = 0;
  uint32_t channel_id = 0;
};

// A client's text message, parsed. `error` is set (and nothing else) when it is not one the
// server takes: not JSON, no "op", an op it does not offer, a field missing or of a wrong type.
struct ClientMessage {
  enum class Op { kSubscribe, kUnsubscribe, kInvalid };
  Op op = Op::kInvalid;
  std::vector<Subscription> subscribe;
  std::vector<uint32_t> unsubscribe;
  std::string error;
};
ClientMessage ParseClientMessage(std::string_view text);

// A binary messageData frame: opcode 1, subscription id (uint32 LE), the message's time
// (uint64 LE, ns), then the encoded message.
std::string MessageDataFrame(uint32_t subscription_id, uint64_t time_ns, std::string_view payload);

}  // namespace bgkmap::foxglove
