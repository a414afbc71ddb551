#include "cluster/nats_client.h"

#include <mutex>

namespace bgkmap::cluster {

Status NatsStatus(natsStatus s, const std::string& what, jsErrCode js_error) {
  std::string text = what + ": " + natsStatus_GetText(s);
  if (js_error != 0)
    text += " (JetStream error " + std::to_string(static_cast<int>(js_error)) + ")";
  if (s == NATS_TIMEOUT || s == NATS_NO_SERVER || s == NATS_CONNECTION_CLOSED ||
      s == NATS_NO_RESPONDERS || s == NATS_NOT_YET_CONNECTED) {
    return Status::Unavailable(text);
  }
  return Status::IoError(text);
}

Result<std::unique_ptr<NatsClient>> NatsClient::Connect(const std::vector<std::string>& servers,
                                                        const std::string& name,
                                                        int64_t timeout_ms) {
  static std::once_flag opened;
  std::call_once(opened, [] { nats_Open(-1); });
  std::string list;
  std::vector<const char*> urls;
  for (const std::string& s : servers) {
    urls.push_back(s.c_str());
    if (!list.empty()) list += ',';
    list += s;
  }
  natsOptions* opts = nullptr;
  natsStatus st = natsOptions_Create(&opts);
  if (st == NATS_OK) st = natsOptions_SetServers(opts, urls.data(), static_cast<int>(urls.size()));
  if (st == NATS_OK) st = natsOptions_SetName(opts, name.c_str());
  if (st == NATS_OK) st = natsOptions_SetTimeout(opts, timeout_ms);
  if (st == NATS_OK) st = natsOptions_SetMaxReconnect(opts, -1);  // forever
  if (st == NATS_OK) st = natsOptions_SetReconnectWait(opts, 250);
  natsConnection* nc = nullptr;
  if (st == NATS_OK) st = natsConnection_Connect(&nc, opts);
  natsOptions_Destroy(opts);
  if (st != NATS_OK) return NatsStatus(st, "cluster.nats: cannot connect to " + list);
  jsOptions jo;
  jsOptions_Init(&jo);
  jo.Wait = timeout_ms;
  jsCtx* js = nullptr;
  st = natsConnection_JetStream(&js, nc, &jo);
  if (st != NATS_OK) {
    natsConnection_Destroy(nc);
    return NatsStatus(st, "cluster.nats: JetStream context");
  }
  return std::unique_ptr<NatsClient>(new NatsClient(nc, js));
}

NatsClient::~NatsClient() {
  jsCtx_Destroy(js_);
  natsConnection_Close(nc_);
  natsConnection_Destroy(nc_);
}

}  // namespace bgkmap::cluster
