// GET /events of the web map: Server-Sent Events telling each page which parts of the map
// changed, fed by the watch hub (the Watch RPC's fan-out), so the page reloads just those tiles.
//
// Each client is one WatchHub subscriber over the whole map: changed tile keys coalesce there
// (bounded by the map's tiles) and are sent, with the map version, when a worker of the pool gets
// to them. At most `max_clients` streams are open (more are answered 503), and at most a token's
// Principal::max_event_streams of one token (more: 429); a client that reads nothing is dropped
// by the HTTP server (write timeout, backlog bound); a comment line every `ping_period` finds
// clients that went away without closing; a stream whose token a reload revoked is closed within
// a second (issue 25).
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "auth/principal.h"
#include "http/http_exchange.h"
#include "serving/map_port.h"
#include "serving/watch_hub.h"

namespace bgkmap {

class EventStreams {
 public:
  EventStreams(MapPort& map, WatchHub& hub, boost::asio::thread_pool& pool, size_t max_clients,
               std::chrono::milliseconds ping_period = std::chrono::seconds(15));
  ~EventStreams();  // Stop()

  // Answers `who`'s request with an event stream (503 when full or stopping, 429 when `who`
  // holds its token's limit). The caller has checked that `who` may watch.
  void Open(const HttpRequest& request, PrincipalRef who, std::shared_ptr<HttpExchange> exchange);
  // Ends every stream; later Open() calls are answered 503. Idempotent.
  void Stop();
  size_t count() const;

 private:
  struct Session;
  void Flush(const std::shared_ptr<Session>& session);
  void Remove(uint64_t key);
  // Pings every ping_period and closes the streams of revoked tokens every second.
  void Ping();

  MapPort& map_;
  WatchHub& hub_;
  boost::asio::thread_pool& pool_;
  const size_t max_clients_;
  const std::chrono::milliseconds ping_period_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool stopped_ = false;
  uint64_t next_key_ = 1;
  std::map<uint64_t, std::shared_ptr<Session>> sessions_;
  std::thread pinger_;
};

}  // namespace bgkmap
