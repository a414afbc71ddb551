// One HTTP request's way back to its client, as the HTTP server (metrics_http.cc) gives it to the
// routes beside /metrics (web_routes.h). A route may answer later, from another thread: a tile is
// rendered off the server's I/O thread, so a slow render never holds back /metrics.
#pragma once

#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>
#include <functional>
#include <string>

namespace bgkmap {

using HttpRequest = boost::beast::http::request<boost::beast::http::string_body>;
using HttpResponse = boost::beast::http::response<boost::beast::http::string_body>;

class HttpExchange {
 public:
  virtual ~HttpExchange() = default;

  // Every method may be called from any thread.

  // Sends the answer (once). The connection then reads the client's next request (keep-alive)
  // or closes.
  virtual void Reply(HttpResponse response) = 0;

  // Instead of Reply: turns the connection into a stream. `head` (status line and headers, up to
  // the blank line) goes first, then every Send() in order, until either side closes. A client
  // that takes no bytes for the write timeout, or lets more than the backlog bound pile up, is
  // disconnected. `on_close` runs once the stream has ended, on the server's thread.
  virtual void StartStream(std::string head, std::function<void()> on_close) = 0;
  // Queues bytes on a stream; false once the stream has ended.
  virtual bool Send(std::string bytes) = 0;
  // Ends the stream.
  virtual void Close() = 0;
};

}  // namespace bgkmap
