#include "cluster/nats_subscription.h"

#include <spdlog/spdlog.h>

#include <chrono>

namespace bgkmap::cluster {

Result<std::unique_ptr<AsyncSubscription>> AsyncSubscription::Start(
    natsConnection* nc, const std::string& subject, const std::string& queue,
    std::function<void(natsMsg*)> handler) {
  std::unique_ptr<AsyncSubscription> s(new AsyncSubscription(std::move(handler)));
  natsSubscription* raw = nullptr;
  natsStatus st = queue.empty()
                      ? natsConnection_Subscribe(&raw, nc, subject.c_str(),
                                                 &AsyncSubscription::OnMessage, s.get())
                      : natsConnection_QueueSubscribe(&raw, nc, subject.c_str(), queue.c_str(),
                                                      &AsyncSubscription::OnMessage, s.get());
  if (st != NATS_OK) return NatsStatus(st, "subscribe to " + subject);
  s->sub_.reset(raw);
  st = natsSubscription_SetOnCompleteCB(raw, &AsyncSubscription::OnComplete, s.get());
  if (st != NATS_OK) {
    // Closed already (its connection is closing): a handler may still be running and nothing
    // will say when it returns, so the object is left to it (a leak, never a use after free).
    natsSubscription_Unsubscribe(raw);
    static_cast<void>(s.release());
    return NatsStatus(st, "watch the subscription to " + subject);
  }
  return s;
}

AsyncSubscription::~AsyncSubscription() {
  BeginStop();
  std::unique_lock lock(mu_);
  // A handler returns within seconds (a tile fetch waits at most 2 s for the log, less once its
  // replica stops); the drain is bounded by kDrainMs. Said if it takes longer, never given up.
  while (!completed_cv_.wait_for(lock, std::chrono::seconds(10), [this] { return completed_; })) {
    spdlog::warn("event=nats_subscription_stop_waiting subject=\"{}\"",
                 sub_ ? natsSubscription_GetSubject(sub_.get()) : "");
  }
  lock.unlock();
  // A drain that completed removed the interest and had its PONG back: nats.c's read loop is
  // past every message for it (QuiesceSubscription's reason, nats_client.h). One that could not
  // reach the server is not flushed again: a silent server sends nothing to race with.
  sub_.reset();
}

void AsyncSubscription::BeginStop() {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    stopping_ = true;
  }
  // Not under mu_: nats.c's threads take their own locks, then call OnComplete (which takes mu_).
  // A drain that cannot start (the connection is closed or closing) closes the subscription.
  if (natsSubscription_DrainTimeout(sub_.get(), kDrainMs) != NATS_OK) {
    natsSubscription_Unsubscribe(sub_.get());
  }
}

void AsyncSubscription::OnMessage(natsConnection*, natsSubscription*, natsMsg* msg, void* self) {
  static_cast<AsyncSubscription*>(self)->handler_(msg);
}

void AsyncSubscription::OnComplete(void* self) {
  auto* s = static_cast<AsyncSubscription*>(self);
  // Notified under the lock: the destructor cannot return (and free the lock) before this
  // function's last access to the object, the unlock.
  std::lock_guard lock(s->mu_);
  s->completed_ = true;
  s->completed_cv_.notify_all();
}

}  // namespace bgkmap::cluster
