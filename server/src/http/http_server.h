// bgkmapd's HTTP endpoint (server.metrics_address, `--http`): a small HTTP/1.1 server (Boost.Beast
// on its own Boost.Asio thread) serving GET /metrics, the live web map with its event stream,
// and /login. /metrics answers with whatever `render` returns, in the Prometheus text format's
// content type (what is exported: metrics.{h,cc}).
//
// Every other path goes to Options::routes (the web map, web_routes.h) if set, else is 404; every
// other method on /metrics is 405. A /metrics response closes its connection; web routes keep it
// alive. A request must arrive whole within Options::read_timeout and fit in
// Options::max_request_bytes: a malformed or oversized request is answered 400/413/431, a slow
// or idle client is disconnected at the timeout. A client holds nothing but its own connection;
// at most Options::max_connections are open at once, and when they are, a new connection evicts
// the one that has waited longest for its request (so slow clients cannot lock scrapers out);
// with none waiting, the new one is closed.
//
// With Options::tls all of it is served over TLS (HTTPS). With Options::authorize every request,
// /metrics and the web routes alike, needs a token: an "Authorization: Bearer <token>" header, or
// for a browser the cookie that GET /login?token=<token> sets (HttpOnly, SameSite=Strict, Secure
// over TLS) before it redirects to the page. Without one the answer is 401; with one, the routes
// are told whose it is (a route may refuse a role: /events needs the watch right).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "auth/principal.h"
#include "bgkmap/core/status.h"
#include "http/http_exchange.h"

namespace boost::asio::ssl {
class context;
}

namespace bgkmap {

class HttpServer {
 public:
  // The body of a /metrics response. Runs on the endpoint's thread, one request at a time.
  using Render = std::function<std::string()>;

  struct Options {
    std::chrono::milliseconds read_timeout{5000};  // to receive a request, and to send a reply
    size_t max_request_bytes = 8192;               // request line, headers and body
    size_t max_connections = 64;                   // open at the same time
    // Answers every path but /metrics and /login, on the endpoint's thread (or later, through
    // the exchange, from any thread), given who asks (AnonymousPrincipal() without `authorize`).
    // Unset: 404.
    std::function<void(const HttpRequest&, PrincipalRef, std::shared_ptr<HttpExchange>)> routes;
    // HTTPS with this context (http/https_context.h); null = plain HTTP. The TLS handshake
    // counts against read_timeout.
    std::shared_ptr<boost::asio::ssl::context> tls;
    // Given each request's credentials as an Authorization header value ("Bearer <token>", from
    // the header or the login cookie): who asks, or null to answer 401 (unset: no check, /login
    // just redirects).
    std::function<PrincipalRef(std::string_view authorization)> authorize;
  };

  // Resolves and binds `address` ("host:port", port 0 = any free port) and listens. Requests
  // wait in the listen backlog until Start(). The error says why the address cannot be used
  // (without naming a config key).
  static Result<std::unique_ptr<HttpServer>> Listen(const std::string& address, Render render,
                                                    Options options);
  static Result<std::unique_ptr<HttpServer>> Listen(const std::string& address, Render render) {
    return Listen(address, std::move(render), Options{});
  }
  ~HttpServer();  // Stop()

  // The bound port (the chosen one for port 0).
  int port() const;

  // Starts serving on the endpoint's own thread.
  void Start();
  // Stops accepting, drops open connections and joins the thread; waits for a render in
  // progress. Idempotent.
  void Stop();

  struct State;  // metrics_http.cc: the io_context, the listener and the open connections

 private:
  explicit HttpServer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace bgkmap
