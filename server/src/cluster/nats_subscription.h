// An asynchronous NATS subscription whose handler is known to have returned for good before the
// object goes away. nats.c runs a subscription's handler on a thread of its own and may run it
// once more after natsSubscription_Unsubscribe or _Drain returned, and
// natsSubscription_WaitForDrainCompletion gives up after its timeout (or at once when the drain
// could not start) while a handler may still run: freeing what the handler uses then is a
// use-after-free. nats.c's completion callback (natsSubscription_SetOnCompleteCB) runs after the
// handler's last return on every path (drained, unsubscribed, drain timed out, connection
// closed); the destructor waits for it.
#pragma once

#include <nats/nats.h>

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "bgkmap/core/status.h"
#include "cluster/nats_client.h"

namespace bgkmap::cluster {

class AsyncSubscription {
 public:
  // Calls `handler` (on nats.c's thread for this subscription, one message at a time; it owns the
  // message) with every message on `subject`, in queue group `queue` unless it is empty.
  static Result<std::unique_ptr<AsyncSubscription>> Start(natsConnection* nc,
                                                          const std::string& subject,
                                                          const std::string& queue,
                                                          std::function<void(natsMsg*)> handler);
  // BeginStop, then blocks until the handler has returned for the last time.
  ~AsyncSubscription();
  AsyncSubscription(const AsyncSubscription&) = delete;
  AsyncSubscription& operator=(const AsyncSubscription&) = delete;

  // Stops taking messages without waiting (the ones already received are still handled, for up
  // to kDrainMs; then nats.c closes the subscription): many subscriptions stop in parallel.
  // Idempotent.
  void BeginStop();
  static constexpr int64_t kDrainMs = 5000;

 private:
  explicit AsyncSubscription(std::function<void(natsMsg*)> handler)
      : handler_(std::move(handler)) {}
  static void OnMessage(natsConnection*, natsSubscription*, natsMsg* msg, void* self);
  static void OnComplete(void* self);

  const std::function<void(natsMsg*)> handler_;
  std::mutex mu_;
  std::condition_variable completed_cv_;
  bool stopping_ = false;   // guarded by mu_
  bool completed_ = false;  // guarded by mu_: nats.c will not call the handler again
  NatsPtr<natsSubscription> sub_;
};

}  // namespace bgkmap::cluster
