#include "http/web_routes.h"

#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <boost/beast/http/field.hpp>
#include <boost/beast/http/status.hpp>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

#include "bgkmap/core/georeference.h"
#include "http/tile_png.h"
#include "http/web_assets.h"

namespace bgkmap {
namespace {

namespace http = boost::beast::http;

HttpResponse Text(const HttpRequest& request, http::status status, std::string body) {
  HttpResponse r{status, request.version()};
  r.set(http::field::content_type, "text/plain; charset=utf-8");
  r.body() = std::move(body) + "\n";
  return r;
}

HttpResponse Body(const HttpRequest& request, std::string_view content_type, std::string body) {
  HttpResponse r{http::status::ok, request.version()};
  r.set(http::field::content_type,
        boost::beast::string_view(content_type.data(), content_type.size()));
  r.set(http::field::cache_control, "no-cache");
  r.body() = std::move(body);
  return r;
}

// A served-map error as HTTP: a corrupt tile or an unreadable store is the server's fault.
HttpResponse ReadFailed(const HttpRequest& request, const Status& s) {
  return Text(request,
              s.code() == Status::Code::kIoError ? http::status::service_unavailable
                                                 : http::status::internal_server_error,
              s.message());
}

template <typename T>
bool ParseInteger(std::string_view text, T* out) {
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, *out);
  return ec == std::errc() && p == end && !text.empty();
}

bool ParseNumber(std::string_view text, double* out) {
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, *out);
  return ec == std::errc() && p == end && !text.empty() && std::isfinite(*out);
}

// The value of `key` in a query string "a=1&b=2" (no percent-decoding: numbers only).
std::optional<std::string_view> QueryValue(std::string_view query, std::string_view key) {
  while (!query.empty()) {
    const size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    const size_t eq = pair.find('=');
    if (eq != std::string_view::npos && pair.substr(0, eq) == key) return pair.substr(eq + 1);
    if (amp == std::string_view::npos) break;
    query.remove_prefix(amp + 1);
  }
  return std::nullopt;
}

// A fully transparent tile: where the map has no tile at all, nothing is read.
const std::string& EmptyTilePng() {
  static const std::string png =
      EncodePng(std::vector<uint8_t>(static_cast<size_t>(kWebTilePixels) * kWebTilePixels * 4, 0),
                kWebTilePixels, kWebTilePixels);
  return png;
}

// The JSON of one point as `bgkmap points` prints it (NaN: null).
nlohmann::json PointJson(double x, double y, const CellEstimate& e) {
  nlohmann::json p = {{"x", x}, {"y", y}};
  for (Layer l :
       {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability,
        Layer::kTraversabilityVariance, Layer::kState, Layer::kDisagreement, Layer::kBlockReason}) {
    const double v = e.Get(l);
    p[std::string(LayerName(l))] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  }
  return p;
}

// The fleet for the page: each robot's latest pose and its recent trajectory (RobotStats). Read
// from the registry under its lock alone, so it is answered on the HTTP thread.
nlohmann::json RobotsJson(const std::vector<RobotStats>& robots) {
  nlohmann::json list = nlohmann::json::array();
  for (const RobotStats& r : robots) {
    nlohmann::json trail = nlohmann::json::array();
    for (const RobotPose& p : r.recent_poses) trail.push_back({p.x, p.y});
    nlohmann::json robot = {{"id", r.robot_id},
                            {"last_sequence", r.last_sequence},
                            {"pose", nullptr},
                            {"trail", trail}};
    if (!r.recent_poses.empty()) {
      const RobotPose& p = r.recent_poses.back();
      robot["pose"] = {{"x", p.x}, {"y", p.y}, {"yaw", p.yaw}, {"sequence", p.sequence}};
    }
    list.push_back(robot);
  }
  return {{"robots", list}};
}

// Where the map frame sits (null: a local frame): the page adds the origin to the cursor's x, y.
nlohmann::json GeoreferenceJson(const Georeference& g) {
  if (g.empty()) return nullptr;
  return {{"crs", g.crs}, {"origin", g.origin}};
}

nlohmann::json WebLayerNames() {
  nlohmann::json names = nlohmann::json::array();
  for (Layer l : kWebLayers) names.push_back(std::string(LayerName(l)));
  return names;
}

}  // namespace

WebRoutes::WebRoutes(MapPort& map, WatchHub& hub, boost::asio::thread_pool& pool,
                     std::atomic<uint32_t>& queries, const ServerLimits& limits,
                     WebRoutesOptions options)
    : map_(map),
      pool_(pool),
      queries_(queries),
      limits_(limits),
      options_(options),
      min_zoom_(WebMinZoom(limits.max_region_cells)),
      events_(map, hub, pool, options.max_event_clients) {}

void WebRoutes::Handle(const HttpRequest& request, PrincipalRef who,
                       std::shared_ptr<HttpExchange> exchange) {
  const std::string_view target(request.target().data(), request.target().size());
  const size_t question = target.find('?');
  const std::string_view path = target.substr(0, question);
  const std::string_view query =
      question == std::string_view::npos ? std::string_view() : target.substr(question + 1);
  if (request.method() != http::verb::get) {
    HttpResponse r = Text(request, http::status::method_not_allowed, "method not allowed: use GET");
    r.set(http::field::allow, "GET");
    exchange->Reply(std::move(r));
    return;
  }
  const std::string_view asset_name = path == "/" ? "/static/index.html" : path;
  if (const WebAsset* asset = FindWebAsset(asset_name)) {
    HttpResponse r = Body(request, asset->content_type, std::string(asset->bytes));
    exchange->Reply(std::move(r));
    return;
  }
  constexpr std::string_view kTiles = "/tiles/";
  if (path.substr(0, kTiles.size()) == kTiles) {
    Tile(request, path.substr(kTiles.size()), std::move(exchange));
  } else if (path == "/points") {
    Points(request, query, std::move(exchange));
  } else if (path == "/map.json") {
    MapJson(request, std::move(exchange));
  } else if (path == "/robots.json") {
    exchange->Reply(Body(request, "application/json", RobotsJson(map_.Robots()).dump(2) + "\n"));
  } else if (path == "/events") {
    if (!who->Has(Right::kWatch)) {
      // The HTTP twin of Watch, which the role may not call over gRPC either.
      exchange->Reply(Text(request, http::status::forbidden,
                           "forbidden: token '" + who->name + "' has role " + RoleName(who->role) +
                               ", which may not watch (GET /events needs the watch right)"));
      return;
    }
    events_.Open(request, std::move(who), std::move(exchange));
  } else {
    exchange->Reply(Text(request, http::status::not_found,
                         "not found: bgkmapd serves /, /tiles/, /points, /events, /map.json, "
                         "/robots.json, /metrics (docs/webmap.md)"));
  }
}

void WebRoutes::OffThread(const HttpRequest& request, std::shared_ptr<HttpExchange> exchange,
                          std::function<HttpResponse()> work) {
  auto busy = [&](const std::string& why) {
    HttpResponse r = Text(request, http::status::service_unavailable, why + "; retry later");
    r.set(http::field::retry_after, "1");
    exchange->Reply(std::move(r));
  };
  if (running_.fetch_add(1) >= options_.max_renders) {
    running_.fetch_sub(1);
    busy("busy: " + std::to_string(options_.max_renders) + " web map reads running");
    return;
  }
  if (queries_.fetch_add(1) >= limits_.max_concurrent_queries) {
    queries_.fetch_sub(1);
    running_.fetch_sub(1);
    busy("server.max_concurrent_queries = " + std::to_string(limits_.max_concurrent_queries) +
         " queries are already running");
    return;
  }
  boost::asio::post(pool_, [this, exchange = std::move(exchange), work = std::move(work),
                            version = request.version()] {
    HttpResponse r;
    try {
      r = work();
    } catch (const std::exception& e) {  // out of memory, say
      spdlog::error("event=web_request_failed reason=\"{}\"", e.what());
      r = HttpResponse{http::status::internal_server_error, version};
      r.body() = "cannot answer\n";
    }
    queries_.fetch_sub(1);
    running_.fetch_sub(1);
    exchange->Reply(std::move(r));
  });
}

void WebRoutes::Tile(const HttpRequest& request, std::string_view rest,
                     std::shared_ptr<HttpExchange> exchange) {
  // {layer}/{z}/{x}/{y}.png
  std::string_view parts[4];
  for (int i = 0; i < 4; ++i) {
    const size_t slash = rest.find('/');
    if ((i < 3) == (slash == std::string_view::npos)) {
      exchange->Reply(Text(request, http::status::not_found,
                           "not found: tiles are /tiles/{layer}/{z}/{x}/{y}.png"));
      return;
    }
    parts[i] = rest.substr(0, slash);
    if (slash != std::string_view::npos) rest.remove_prefix(slash + 1);
  }
  constexpr std::string_view kPng = ".png";
  if (parts[3].size() <= kPng.size() || parts[3].substr(parts[3].size() - kPng.size()) != kPng) {
    exchange->Reply(Text(request, http::status::not_found, "not found: tiles end in .png"));
    return;
  }
  parts[3].remove_suffix(kPng.size());
  const Result<Layer> layer = ParseWebLayer(parts[0]);
  if (!layer.ok()) {
    exchange->Reply(Text(request, http::status::not_found, layer.status().message()));
    return;
  }
  int z = 0;
  int64_t x = 0, y = 0;
  if (!ParseInteger(parts[1], &z) || !ParseInteger(parts[2], &x) || !ParseInteger(parts[3], &y)) {
    exchange->Reply(
        Text(request, http::status::bad_request, "bad tile: z, x and y must be integers"));
    return;
  }
  const Result<WebTileCells> cells =
      TileCells(z, x, y, min_zoom_, map_.geometry().resolution(), limits_.max_coordinate);
  if (!cells.ok()) {
    exchange->Reply(Text(request, http::status::not_found, cells.status().message()));
    return;
  }
  OffThread(request, std::move(exchange),
            [this, version = request.version(), cells = *cells, layer = *layer]() -> HttpResponse {
              HttpRequest head{http::verb::get, "", version};
              const GridGeometry& g = map_.geometry();
              Result<std::vector<TileKey>> known =
                  map_.ListKnownTiles(g.TileOf(cells.box.min), g.TileOf(cells.box.max));
              if (!known.ok()) return ReadFailed(head, known.status());
              if (known->empty()) return Body(head, "image/png", EmptyTilePng());
              Result<Raster> raster = map_.ReadRegion(cells.box, {layer}, cells.stride);
              if (!raster.ok()) return ReadFailed(head, raster.status());
              return Body(
                  head, "image/png",
                  EncodePng(RenderTile(*raster, layer, cells), kWebTilePixels, kWebTilePixels));
            });
}

void WebRoutes::Points(const HttpRequest& request, std::string_view query,
                       std::shared_ptr<HttpExchange> exchange) {
  double xy[2];
  const char* names[2] = {"x", "y"};
  for (int i = 0; i < 2; ++i) {
    const std::optional<std::string_view> v = QueryValue(query, names[i]);
    if (!v || !ParseNumber(*v, &xy[i])) {
      exchange->Reply(Text(request, http::status::bad_request,
                           std::string("bad point: ") + names[i] + " must be a finite number"));
      return;
    }
    if (std::abs(xy[i]) > limits_.max_coordinate) {
      exchange->Reply(
          Text(request, http::status::bad_request,
               std::string("bad point: |") + names[i] +
                   "| exceeds server.max_coordinate = " + std::to_string(limits_.max_coordinate)));
      return;
    }
  }
  OffThread(request, std::move(exchange),
            [this, x = xy[0], y = xy[1], version = request.version()]() -> HttpResponse {
              HttpRequest head{http::verb::get, "", version};
              const CellIndex cell[] = {map_.geometry().CellAt(x, y)};
              const uint64_t map_version = map_.applied_version();
              Result<std::vector<CellEstimate>> read = map_.ReadCells(cell);
              if (!read.ok()) return ReadFailed(head, read.status());
              const nlohmann::json out = {{"map_version", map_version},
                                          {"points", {PointJson(x, y, (*read)[0])}}};
              return Body(head, "application/json", out.dump(2) + "\n");
            });
}

void WebRoutes::MapJson(const HttpRequest& request, std::shared_ptr<HttpExchange> exchange) {
  OffThread(request, std::move(exchange), [this, version = request.version()]() -> HttpResponse {
    HttpRequest head{http::verb::get, "", version};
    const MapState state = map_.State();
    const MapSummary& summary = state.summary;
    const GridGeometry& g = map_.geometry();
    const double res = g.resolution();
    nlohmann::json bounds = nullptr;
    if (!summary.known_bounds.empty()) {
      const CellBox& b = summary.known_bounds;
      bounds = {b.min.x * res, b.min.y * res, (b.max.x + 1) * res, (b.max.y + 1) * res};
    }
    const nlohmann::json out = {{"resolution", res},
                                {"tile_size", g.tile_size()},
                                {"tile_pixels", kWebTilePixels},
                                {"min_zoom", min_zoom_},
                                {"max_zoom", kWebMaxZoom},
                                {"map_version", map_.applied_version()},
                                {"known_cells", summary.known_cells},
                                {"bounds", bounds},
                                {"layers", WebLayerNames()},
                                {"georeference", GeoreferenceJson(state.georeference)}};
    return Body(head, "application/json", out.dump(2) + "\n");
  });
}

}  // namespace bgkmap
