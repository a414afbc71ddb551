#include "foxglove/protocol.h"

#include <limits>
#include <nlohmann/json.hpp>

namespace bgkmap::foxglove {
namespace {

using nlohmann::json;

// An id field: an integer in uint32's range.
bool ReadId(const json& object, const char* key, uint32_t* out) {
  auto it = object.find(key);
  if (it == object.end() || !it->is_number_integer()) return false;
  const int64_t v = it->get<int64_t>();
  if (v < 0 || v > std::numeric_limits<uint32_t>::max()) return false;
  *out = static_cast<uint32_t>(v);
  return true;
}

ClientMessage Invalid(std::string why) {
  ClientMessage m;
  m.error = std::move(why);
  return m;
}

ClientMessage ParseSubscribe(const json& doc) {
  auto list = doc.find("subscriptions");
  if (list == doc.end() || !list->is_array()) {
    return Invalid("subscribe: 'subscriptions' must be an array of {id, channelId}");
  }
  ClientMessage m;
  m.op = ClientMessage::Op::kSubscribe;
  for (const json& s : *list) {
    Subscription sub;
    if (!s.is_object() || !ReadId(s, "id", &sub.id) || !ReadId(s, "channelId", &sub.channel_id)) {
      return Invalid("subscribe: each subscription needs integer 'id' and 'channelId' (uint32)");
    }
    m.subscribe.push_back(sub);
  }
  return m;
}

ClientMessage ParseUnsubscribe(const json& doc) {
  auto list = doc.find("subscriptionIds");
  if (list == doc.end() || !list->is_array()) {
    return Invalid("unsubscribe: 'subscriptionIds' must be an array of integers");
  }
  ClientMessage m;
  m.op = ClientMessage::Op::kUnsubscribe;
  for (const json& id : *list) {
    if (!id.is_number_integer() || id.get<int64_t>() < 0 ||
        id.get<int64_t>() > std::numeric_limits<uint32_t>::max()) {
      return Invalid("unsubscribe: 'subscriptionIds' must be an array of integers (uint32)");
    }
    m.unsubscribe.push_back(static_cast<uint32_t>(id.get<int64_t>()));
  }
  return m;
}

}  // namespace

std::string ServerInfoJson(std::string_view name, std::string_view session_id) {
  return json{{"op", "serverInfo"},
              {"name", name},
              {"capabilities", json::array()},
              {"supportedEncodings", json::array()},
              {"metadata", json::object()},
              {"sessionId", session_id}}
      .dump();
}

std::string AdvertiseJson(const std::vector<Channel>& channels) {
  json list = json::array();
  for (const Channel& c : channels) {
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", "protobuf"},
                    {"schemaName", c.schema_name},
                    {"schema", c.schema_base64},
                    {"schemaEncoding", "protobuf"}});
  }
  return json{{"op", "advertise"}, {"channels", std::move(list)}}.dump();
}

std::string StatusJson(StatusLevel level, std::string_view message) {
  // Replacement instead of an exception for bytes that are not UTF-8 (echoed client text).
  return json{{"op", "status"}, {"level", static_cast<int>(level)}, {"message", message}}.dump(
      -1, ' ', false, json::error_handler_t::replace);
}

ClientMessage ParseClientMessage(std::string_view text) {
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return Invalid("not a JSON message");
  if (!doc.is_object()) return Invalid("a message must be a JSON object");
  auto op = doc.find("op");
  if (op == doc.end() || !op->is_string()) return Invalid("a message needs a string 'op'");
  const std::string name = op->get<std::string>();
  if (name == "subscribe") return ParseSubscribe(doc);
  if (name == "unsubscribe") return ParseUnsubscribe(doc);
  return Invalid("op '" + name +
                 "' is not offered: bgkmapd takes subscribe and unsubscribe (no capabilities)");
}

std::string MessageDataFrame(uint32_t subscription_id, uint64_t time_ns, std::string_view payload) {
  std::string frame;
  frame.reserve(1 + 4 + 8 + payload.size());
  frame.push_back(static_cast<char>(0x01));
  for (int i = 0; i < 4; ++i)
    frame.push_back(static_cast<char>((subscription_id >> (8 * i)) & 0xff));
  for (int i = 0; i < 8; ++i) frame.push_back(static_cast<char>((time_ns >> (8 * i)) & 0xff));
  frame.append(payload);
  return frame;
}

}  // namespace bgkmap::foxglove
