// The live web map's routes beside GET /metrics (docs/webmap.md):
//   GET /                                   the page (Leaflet, embedded at build time)
//   GET /static/NAME                        its scripts, styles and images
//   GET /map.json                           resolution, zoom range, known bounds, version
//   GET /tiles/{layer}/{z}/{x}/{y}.png      a tile rendered from the map (tile_png.h)
//   GET /points?x=X&y=Y                     a cell's values, as `bgkmap points` prints them
//   GET /events                             Server-Sent Events: changed tiles (sse.h)
// Reads go through the served map like the RPCs' (pinned, locked, never from a corrupt tile) and
// run on the query pool, never on the HTTP thread; at most `max_renders` at once, and each counts
// against server.max_concurrent_queries with the RPCs' queries (beyond either: 503).
#pragma once

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <memory>

#include "auth/principal.h"
#include "bgkmap/server/server_config.h"
#include "http/http_exchange.h"
#include "http/sse.h"
#include "serving/map_port.h"
#include "serving/watch_hub.h"

namespace bgkmap {

struct WebRoutesOptions {
  size_t max_renders = 8;                       // tile, point and map.json reads at once
  size_t max_event_clients = kMaxEventStreams;  // open /events streams
};

class WebRoutes {
 public:
  // `queries` counts the queries running (the RPC handlers' counter).
  WebRoutes(MapPort& map, WatchHub& hub, boost::asio::thread_pool& pool,
            std::atomic<uint32_t>& queries, const ServerLimits& limits, WebRoutesOptions options);

  // Answers `request` (any path but /metrics) from `who`. Called on the HTTP thread: it only
  // parses and hands the work to the pool.
  void Handle(const HttpRequest& request, PrincipalRef who, std::shared_ptr<HttpExchange> exchange);
  // Ends the event streams; called before the HTTP server stops.
  void Stop() { events_.Stop(); }

  int min_zoom() const { return min_zoom_; }

 private:
  void Tile(const HttpRequest& request, std::string_view rest,
            std::shared_ptr<HttpExchange> exchange);
  void Points(const HttpRequest& request, std::string_view query,
              std::shared_ptr<HttpExchange> exchange);
  void MapJson(const HttpRequest& request, std::shared_ptr<HttpExchange> exchange);
  // Runs `work` on the pool unless max_renders are running (then 503 at once).
  void OffThread(const HttpRequest& request, std::shared_ptr<HttpExchange> exchange,
                 std::function<HttpResponse()> work);

  MapPort& map_;
  boost::asio::thread_pool& pool_;
  std::atomic<uint32_t>& queries_;
  const ServerLimits limits_;
  const WebRoutesOptions options_;
  const int min_zoom_;
  std::atomic<size_t> running_{0};
  EventStreams events_;
};

}  // namespace bgkmap
