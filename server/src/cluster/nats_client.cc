#include "cluster/nats_client.h"

#include <mutex>

#include "bgkmap/server/server_config.h"

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

void QuiesceSubscription(natsConnection* nc, natsSubscription* sub, int64_t timeout_ms) {
  natsSubscription_Unsubscribe(sub);
  if (nc != nullptr) natsConnection_FlushTimeout(nc, timeout_ms);
}

void QuiescingDeleter::operator()(natsSubscription* s) const {
  QuiesceSubscription(nc, s);
  natsSubscription_Destroy(s);
}

Result<std::unique_ptr<NatsClient>> NatsClient::Connect(const std::vector<std::string>& servers,
                                                        const std::string& name,
                                                        const NatsSecurity& security,
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
  // The files are read here: a bad one is named, never its contents.
  auto refuse = [&](const std::string& key, const std::string& file) {
    natsOptions_Destroy(opts);
    return Status::FailedPrecondition("cluster." + key + " '" + file +
                                      "': " + nats_GetLastError(nullptr));
  };
  if (st == NATS_OK && !security.credentials_file.empty() &&
      natsOptions_SetUserCredentialsFromFiles(opts, security.credentials_file.c_str(), nullptr) !=
          NATS_OK) {
    return refuse("nats_credentials", security.credentials_file);
  }
  if (st == NATS_OK && !security.ca_file.empty() &&
      (natsOptions_SetSecure(opts, true) != NATS_OK ||
       natsOptions_LoadCATrustedCertificates(opts, security.ca_file.c_str()) != NATS_OK)) {
    return refuse("nats_tls.ca_file", security.ca_file);
  }
  if (st == NATS_OK && !security.cert_file.empty() &&
      (natsOptions_SetSecure(opts, true) != NATS_OK ||
       natsOptions_LoadCertificatesChain(opts, security.cert_file.c_str(),
                                         security.key_file.c_str()) != NATS_OK)) {
    return refuse("nats_tls.cert_file", security.cert_file);
  }
  natsConnection* nc = nullptr;
  if (st == NATS_OK) st = natsConnection_Connect(&nc, opts);
  natsOptions_Destroy(opts);
  if (st != NATS_OK) {
    return NatsStatus(st, "cluster.nats: cannot connect to " + RedactUrlSecrets(list) + " (" +
                              nats_GetLastError(nullptr) + ")");
  }
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
