// A connection to a NATS cluster with JetStream, owned, and the nats.c handles the cluster code
// uses wrapped so they are released on every path. nats.c reconnects by itself (to any server
// of the cluster it knows of); calls made while it is reconnecting fail with a timeout, which
// the callers treat as "retry".
#pragma once

#include <nats/nats.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::cluster {

struct NatsDeleter {
  void operator()(natsMsg* m) const { natsMsg_Destroy(m); }
  void operator()(natsSubscription* s) const { natsSubscription_Destroy(s); }
  void operator()(kvEntry* e) const { kvEntry_Destroy(e); }
  void operator()(kvStore* kv) const { kvStore_Destroy(kv); }
  void operator()(jsPubAck* a) const { jsPubAck_Destroy(a); }
  void operator()(jsMsgMetaData* m) const { jsMsgMetaData_Destroy(m); }
  void operator()(jsStreamInfo* i) const { jsStreamInfo_Destroy(i); }
};
template <typename T>
using NatsPtr = std::unique_ptr<T, NatsDeleter>;

// Removes interest in `sub`, then waits (up to `timeout_ms`) for a round trip to the server on
// `nc`. nats.c 3.4's read loop looks a message's subscription up, lets go of the table's lock and
// only then locks the subscription, without holding a reference (fixed in nats.c 3.6.1, Debian
// ships 3.4.1): a subscription freed in that window is locked after its free (a crash, or a
// lock that never comes: the one hang seen in the cluster tests). The read loop handles the
// server's PONG after every message read before it, and none arrives for `sub` once its
// interest is gone, so after the round trip no message for it is half handled.
void QuiesceSubscription(natsConnection* nc, natsSubscription* sub, int64_t timeout_ms = 2000);

// A subscription that messages may be reaching when it is released (a log reader): quiesced
// first (QuiesceSubscription), then destroyed.
struct QuiescingDeleter {
  natsConnection* nc = nullptr;
  void operator()(natsSubscription* s) const;
};
using LiveSubscription = std::unique_ptr<natsSubscription, QuiescingDeleter>;

// `what`: what failed, then nats.c's text for `s` and JetStream's error code if any.
Status NatsStatus(natsStatus s, const std::string& what,
                  jsErrCode js_error = static_cast<jsErrCode>(0));

// Runs `call` (returning natsStatus) until it succeeds or `timeout_ms` passed, pausing between
// tries: a JetStream cluster answers "no responders" or times out while it elects a new leader
// for a stream whose leader died (a few seconds). Only for calls that are safe to repeat.
template <typename Call>
natsStatus RetryWhileElecting(Call call, int64_t timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    const natsStatus st = call();
    // NOT_FOUND is an answer (no such key), not a failure to get one.
    if (st == NATS_OK || st == NATS_NOT_FOUND || std::chrono::steady_clock::now() >= deadline) {
      return st;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

// How a shard proves itself to NATS and checks the servers (cluster.nats_credentials,
// cluster.nats_tls); every field may be empty.
struct NatsSecurity {
  std::string credentials_file;     // a .creds file: the user's JWT and nkey seed
  std::string ca_file;              // set: TLS, the servers' certificates checked against these CAs
  std::string cert_file, key_file;  // the client certificate, for servers that verify clients
};

class NatsClient {
 public:
  // Connects to any of `servers` ("nats://host:port"), reconnecting forever afterwards.
  // Unavailable naming the servers (secrets in their URLs hidden) if none answers within
  // `timeout_ms`; FailedPrecondition naming the setting if a file of `security` is unusable.
  static Result<std::unique_ptr<NatsClient>> Connect(const std::vector<std::string>& servers,
                                                     const std::string& name,
                                                     const NatsSecurity& security = {},
                                                     int64_t timeout_ms = 5000);
  ~NatsClient();
  NatsClient(const NatsClient&) = delete;
  NatsClient& operator=(const NatsClient&) = delete;

  natsConnection* connection() const { return nc_; }
  jsCtx* jetstream() const { return js_; }
  // The largest message the servers accept (their max_payload).
  int64_t max_payload() const { return natsConnection_GetMaxPayload(nc_); }

 private:
  NatsClient(natsConnection* nc, jsCtx* js) : nc_(nc), js_(js) {}
  natsConnection* nc_;
  jsCtx* js_;
};

}  // namespace bgkmap::cluster
