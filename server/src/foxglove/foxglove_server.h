// bgkmapd's Foxglove port (`--foxglove HOST:PORT`, server.foxglove.address; docs/foxglove.md):
// the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1) on Boost.Beast, on its own
// Boost.Asio thread. Channels: /map (foxglove.Grid of the configured region), /tf
// (foxglove.FrameTransforms: map -> each robot) and /scans (foxglove.PointCloud: each robot's
// last scan), fed by a LiveFeed; clients subscribe and unsubscribe.
//
// The upgrade request must arrive within Options::handshake_timeout and offer the subprotocol
// (else 400); with tokens it carries one ("Authorization: Bearer <token>", or `?token=<token>`
// in the URL for viewers that cannot set headers) whose role may watch (else 401 / 403); at most
// Options::max_clients are connected (else 503). With Options::tls everything is over TLS (wss).
// A client that lets more than Options::max_queued_bytes wait unsent is dropped (a message is
// always queued when nothing waits, so the bound never refuses one large grid). A bad message
// from a client is answered with a status message (level error) naming what was wrong; the
// connection stays open.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "auth/token_table.h"
#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "serving/latest_scans.h"
#include "serving/map_port.h"
#include "serving/watch_hub.h"

namespace boost::asio::ssl {
class context;
}

namespace bgkmap::foxglove {

struct Options {
  CellBox region;             // the /map grid's cells
  std::vector<Layer> layers;  // its fields
  size_t max_clients = 16;
  size_t max_queued_bytes = 64u << 20;
  std::chrono::milliseconds handshake_timeout{5000};
  std::chrono::seconds idle_timeout{60};  // a client that answers no ping for this long goes
  size_t max_request_bytes = 8192;        // the upgrade request
  size_t max_message_bytes = 64u << 10;   // a client's message
  std::shared_ptr<boost::asio::ssl::context> tls;  // null: plain ws://
  const TokenTable* tokens = nullptr;              // null: no tokens
};

class FoxgloveServer {
 public:
  // Binds `address` ("host:port", port 0 = any free port); clients wait in the backlog until
  // Start(). The error says why the address cannot be used.
  static Result<std::unique_ptr<FoxgloveServer>> Listen(const std::string& address, MapPort& map,
                                                        WatchHub& hub, LatestScans& scans,
                                                        boost::asio::thread_pool& pool,
                                                        Options options);
  ~FoxgloveServer();  // Stop()

  int port() const;
  void Start();
  // Stops the feed, closes every connection and joins the thread. Idempotent.
  void Stop();
  size_t client_count() const;

  struct State;

 private:
  explicit FoxgloveServer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace bgkmap::foxglove
