#include "http/http_server.h"

#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <type_traits>

#include "bgkmap/server/host_port.h"
#include "http/http_exchange.h"
#include "http/login_cookie.h"

namespace bgkmap {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

constexpr const char* kMetricsPath = "/metrics";
constexpr const char* kLoginPath = "/login";
constexpr const char* kMetricsContentType = "text/plain; version=0.0.4; charset=utf-8";
// How long, and for how many bytes, a connection waits for the client to close after the
// response.
constexpr std::chrono::seconds kLingerTime{1};
constexpr size_t kMaxLingerBytes = 1 << 20;
// Bytes an event stream may hold for a client that reads too slowly.
constexpr size_t kMaxStreamBacklog = 1 << 20;

// What the server holds of a connection, plain or TLS (Connection<Stream> below).
class ConnectionBase {
 public:
  // Aborts whatever is pending and frees the slot; the handlers then release the connection.
  virtual void Close() = 0;
  // Waiting on its client: for (or receiving) a request, in the TLS handshake, or for the client
  // to take a response (issue 25: pipelining clients that read nothing held every slot). The
  // connections a full server evicts, oldest first. 0 while a request is being answered or a
  // stream is open.
  uint64_t reading_since() const { return reading_since_; }

 protected:
  ~ConnectionBase() = default;
  uint64_t reading_since_ = 0;
};

}  // namespace

struct HttpServer::State {
  State(Render r, Options o) : render(std::move(r)), options(o) {}

  void Accept();
  // The token check, before any route: a 401 for a request without a valid token, or the
  // answer to /login; nothing if the request may go on, with `*who` its caller.
  std::optional<HttpResponse> CheckAccess(const HttpRequest& request, PrincipalRef* who) const;
  // Answers a parsed request for /metrics (or, without routes, any path): the status and body.
  HttpResponse Answer(const HttpRequest& request);

  // Closes the listener and every connection, then stops the loop. On the io thread.
  void CloseAll();

  const Render render;
  const Options options;
  // The open connections, touched on the io thread only. Declared before the io_context: its
  // destruction destroys the handlers still pending, and with them connections, which remove
  // themselves from here.
  std::set<ConnectionBase*> connections;
  uint64_t read_sequence = 0;  // orders the connections waiting for a request
  asio::io_context io;
  tcp::acceptor acceptor{io};
  asio::steady_timer retry{io};
  int port = 0;
  std::thread thread;
  std::mutex stop_mu;
  bool started = false;
  bool stopped = false;
};

namespace {

// One client connection: reads a request (bounded in time and size), answers it, then reads the
// next one (keep-alive, web routes) or closes (/metrics, errors); or streams events (/events).
// Lives on the io thread; the HttpExchange it hands to the web routes may be called from any
// thread and posts there. `Stream` is beast::tcp_stream, or beast::ssl_stream of one (then the
// TLS handshake comes first, and a closing response sends TLS close_notify).
template <typename Stream>
class Connection final : public ConnectionBase,
                         public std::enable_shared_from_this<Connection<Stream>> {
 public:
  using State = HttpServer::State;
  static constexpr bool kTls = !std::is_same_v<Stream, beast::tcp_stream>;

  template <typename... StreamArgs>
  explicit Connection(State& state, StreamArgs&&... stream_args)
      : stream_(std::forward<StreamArgs>(stream_args)...),
        buffer_(state.options.max_request_bytes),
        state_(state) {
    state_.connections.insert(this);
  }
  ~Connection() {
    state_.connections.erase(this);
    if (on_close_) on_close_();
  }

  void Open() {
    if constexpr (kTls) {
      // A handshake that trickles is as evictable as a request that does.
      reading_since_ = ++state_.read_sequence;
      Tcp().expires_after(state_.options.read_timeout);
      stream_.async_handshake(
          asio::ssl::stream_base::server, [self = this->shared_from_this()](beast::error_code ec) {
            if (ec) {
              self->reading_since_ = 0;
              spdlog::debug("event=metrics_tls_failed reason=\"{}\"", ec.message());
              return;
            }
            if (!self->closed_->load()) self->Read();
          });
    } else {
      Read();
    }
  }

  void Read() {
    reading_since_ = ++state_.read_sequence;
    parser_.emplace();
    parser_->header_limit(static_cast<uint32_t>(state_.options.max_request_bytes));
    parser_->body_limit(state_.options.max_request_bytes);
    // The whole request must arrive within the timeout, however it trickles in.
    Tcp().expires_after(state_.options.read_timeout);
    http::async_read(
        stream_, buffer_, *parser_,
        [self = this->shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void Close() override {
    state_.connections.erase(this);  // its slot is free now
    closed_->store(true);
    reading_since_ = 0;
    // The hold may be the last owner: released after the socket is closed, at the end.
    const std::shared_ptr<Connection> hold = std::move(hold_);
    Tcp().close();
  }

  // What a route answers through: posts to this connection's thread.
  class Exchange final : public HttpExchange {
   public:
    explicit Exchange(const std::shared_ptr<Connection>& c)
        : connection_(c), executor_(c->Tcp().get_executor()), closed_(c->closed_) {}
    void Reply(HttpResponse response) override {
      asio::post(executor_, [c = connection_, r = std::move(response)]() mutable {
        if (auto self = c.lock()) self->Write(std::move(r));
      });
    }
    void StartStream(std::string head, std::function<void()> on_close) override {
      asio::post(executor_, [c = connection_, h = std::move(head), f = std::move(on_close)] {
        if (auto self = c.lock()) {
          self->StartStream(std::move(h), std::move(f));
        } else {
          f();
        }
      });
    }
    bool Send(std::string bytes) override {
      if (closed_->load()) return false;
      asio::post(executor_, [c = connection_, b = std::move(bytes)]() mutable {
        if (auto self = c.lock()) self->Queue(std::move(b));
      });
      return true;
    }
    void Close() override {
      asio::post(executor_, [c = connection_] {
        if (auto self = c.lock()) self->Close();
      });
    }

   private:
    const std::weak_ptr<Connection> connection_;
    const asio::any_io_executor executor_;
    const std::shared_ptr<std::atomic<bool>> closed_;
  };

 private:
  void OnRead(beast::error_code ec) {
    reading_since_ = 0;
    if (ec == beast::error::timeout || ec == http::error::end_of_stream ||
        ec == http::error::partial_message || ec == asio::error::operation_aborted ||
        ec == asio::error::eof || ec == asio::error::connection_reset ||
        ec == asio::ssl::error::stream_truncated || closed_->load()) {
      return;  // closed, evicted or too slow: nothing to answer
    }
    if (ec) {
      http::status status = http::status::bad_request;
      if (ec == http::error::header_limit || ec == http::error::buffer_overflow) {
        status = http::status::request_header_fields_too_large;
      } else if (ec == http::error::body_limit) {
        status = http::status::payload_too_large;
      }
      spdlog::debug("event=metrics_bad_request reason=\"{}\"", ec.message());
      http::response<http::string_body> response{status, 11};
      const auto reason = http::obsolete_reason(status);
      response.body() = std::string(reason.data(), reason.size()) + "\n";
      keep_alive_ = false;
      Write(std::move(response));
      return;
    }
    const http::request<http::string_body>& request = parser_->get();
    PrincipalRef who;
    if (std::optional<HttpResponse> refused = state_.CheckAccess(request, &who)) {
      keep_alive_ = request.keep_alive();  // a 401 closes (Write: every error does)
      Write(std::move(*refused));
      return;
    }
    const std::string_view target(request.target().data(), request.target().size());
    if (!state_.options.routes || target.substr(0, target.find('?')) == kMetricsPath) {
      keep_alive_ = false;  // a scrape per connection, as before
      Write(state_.Answer(request));
      return;
    }
    // A web route answers later (or on another thread): the connection holds itself meanwhile.
    keep_alive_ = request.keep_alive();
    hold_ = this->shared_from_this();
    state_.options.routes(request, std::move(who),
                          std::make_shared<Exchange>(this->shared_from_this()));
  }

  void Write(http::response<http::string_body> response) {
    hold_.reset();
    if (closed_->load()) return;
    response.set(http::field::server, "bgkmapd");
    if (response[http::field::content_type].empty()) {
      response.set(http::field::content_type, "text/plain; charset=utf-8");
    }
    // An error closes the connection: a confused client starts afresh.
    if (response.result_int() >= 400) keep_alive_ = false;
    response.keep_alive(keep_alive_);
    response.prepare_payload();
    response_ = std::move(response);
    Tcp().expires_after(state_.options.read_timeout);
    reading_since_ = ++state_.read_sequence;  // evictable: the client may not be reading
    http::async_write(stream_, *response_,
                      [self = this->shared_from_this()](beast::error_code write_ec, size_t) {
                        self->reading_since_ = 0;
                        if (write_ec) return;
                        if (self->keep_alive_) {
                          self->Read();
                          return;
                        }
                        self->CloseSend();
                      });
  }

  // After a closing response: tells the client it is whole, then lingers (Drain).
  void CloseSend() {
    if constexpr (kTls) {
      // close_notify, so the client knows the response is whole; then the TCP close.
      Tcp().expires_after(kLingerTime);
      stream_.async_shutdown([self = this->shared_from_this()](beast::error_code) {
        beast::error_code ignored;
        self->Tcp().socket().shutdown(tcp::socket::shutdown_both, ignored);
      });
    } else {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      stream_.expires_after(kLingerTime);
      Drain();
    }
  }

  beast::tcp_stream& Tcp() { return beast::get_lowest_layer(stream_); }

  void StartStream(std::string head, std::function<void()> on_close) {
    hold_.reset();
    on_close_ = std::move(on_close);
    if (closed_->load()) return;
    hold_ = this->shared_from_this();  // until Close(): between writes nothing else holds it
    Queue(std::move(head));
    WatchForClose();
  }

  // A stream's client sends nothing more: a read that ends tells that it has gone (without
  // waiting for a write to fail). On the socket itself, outside the stream's write timeout; over
  // TLS too: nothing reads the TLS stream again, so what the client sends (close_notify) is
  // dropped.
  void WatchForClose() {
    Tcp().socket().async_read_some(asio::buffer(discard_),
                                   [self = this->shared_from_this()](beast::error_code ec, size_t) {
                                     if (ec) {
                                       self->Close();
                                     } else {
                                       self->WatchForClose();
                                     }
                                   });
  }

  // A stream's bytes: written in order; a client that lets kMaxStreamBacklog bytes pile up, or
  // takes nothing for the write timeout, is disconnected.
  void Queue(std::string bytes) {
    if (closed_->load()) return;
    pending_ += bytes;
    if (pending_.size() > kMaxStreamBacklog) {
      spdlog::info("event=web_slow_client_dropped backlog_bytes={}", pending_.size());
      Close();
      return;
    }
    if (writing_) return;
    writing_ = true;
    out_.swap(pending_);
    pending_.clear();
    Tcp().expires_after(state_.options.read_timeout);
    asio::async_write(stream_, asio::buffer(out_),
                      [self = this->shared_from_this()](beast::error_code ec, size_t) {
                        self->writing_ = false;
                        self->out_.clear();
                        if (ec) {
                          self->Close();
                        } else if (!self->pending_.empty()) {
                          self->Queue(std::string());
                        }
                      });
  }

  // After the response: reads and drops what the client still sends until it closes (or the
  // linger time or byte budget runs out). Closing with unread bytes would reset the connection,
  // and a reset can discard the response before the client has read it (an error answered
  // before the whole request was read).
  void Drain() {
    stream_.async_read_some(asio::buffer(discard_),
                            [self = this->shared_from_this()](beast::error_code ec, size_t n) {
                              self->drained_ += n;
                              if (!ec && self->drained_ < kMaxLingerBytes) self->Drain();
                            });
  }

  Stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::optional<http::response<http::string_body>> response_;
  std::array<char, 4096> discard_;
  size_t drained_ = 0;
  State& state_;
  bool keep_alive_ = false;
  std::shared_ptr<Connection> hold_;  // while a route answers, and while a stream is open
  std::shared_ptr<std::atomic<bool>> closed_ = std::make_shared<std::atomic<bool>>(false);
  std::function<void()> on_close_;
  bool writing_ = false;
  std::string pending_, out_;
};

}  // namespace

void HttpServer::State::Accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor.is_open()) return;
    if (ec) {
      // Out of descriptors, say: try again shortly rather than spin.
      spdlog::warn("event=metrics_accept_failed reason=\"{}\"", ec.message());
      retry.expires_after(std::chrono::milliseconds(100));
      retry.async_wait([this](beast::error_code timer_ec) {
        if (!timer_ec) Accept();
      });
      return;
    }
    if (connections.size() >= options.max_connections) {
      // Full: the connection that has waited longest for its request goes (a slow or idle
      // client), so trickling clients cannot hold every slot against a scraper.
      ConnectionBase* oldest = nullptr;
      for (ConnectionBase* c : connections) {
        if (c->reading_since() != 0 &&
            (oldest == nullptr || c->reading_since() < oldest->reading_since())) {
          oldest = c;
        }
      }
      if (oldest != nullptr) oldest->Close();
    }
    if (connections.size() >= options.max_connections) {
      beast::error_code ignored;
      socket.close(ignored);  // every slot answers a request: a scraper retries
    } else if (options.tls != nullptr) {
      std::make_shared<Connection<beast::ssl_stream<beast::tcp_stream>>>(*this, std::move(socket),
                                                                         *options.tls)
          ->Open();
    } else {
      std::make_shared<Connection<beast::tcp_stream>>(*this, std::move(socket))->Open();
    }
    Accept();
  });
}

void HttpServer::State::CloseAll() {
  beast::error_code ignored;
  acceptor.close(ignored);
  retry.cancel();
  // Close() only aborts operations; the connections go when their handlers have run.
  for (ConnectionBase* c : std::set<ConnectionBase*>(connections)) c->Close();
  io.stop();
}

std::optional<HttpResponse> HttpServer::State::CheckAccess(const HttpRequest& request,
                                                           PrincipalRef* who) const {
  const std::string_view target(request.target().data(), request.target().size());
  const std::string_view path = target.substr(0, target.find('?'));
  const unsigned version = request.version() == 10 ? 10 : 11;
  auto unauthorized = [version](std::string body) {
    HttpResponse response{http::status::unauthorized, version};
    response.set(http::field::content_type, "text/plain; charset=utf-8");
    response.set(http::field::www_authenticate, "Bearer");
    response.body() = std::move(body);
    return response;
  };
  if (path == kLoginPath) {
    // The browser's way in: the token from the address, once, into an HttpOnly cookie; the
    // redirect drops it from the address bar.
    const std::string token = LoginTokenFromQuery(target);
    if (options.authorize != nullptr && options.authorize("Bearer " + token) == nullptr) {
      return unauthorized("unauthorized: open /login?token=<a valid token>\n");
    }
    HttpResponse response{http::status::see_other, version};
    response.set(http::field::location, "/");
    response.set(http::field::cache_control, "no-store");
    response.set("Referrer-Policy", "no-referrer");
    if (options.authorize != nullptr) {
      response.set(http::field::set_cookie, LoginCookie(token, options.tls != nullptr));
    }
    return response;
  }
  if (options.authorize == nullptr) {
    *who = AnonymousPrincipal();
    return std::nullopt;
  }
  const auto header = request[http::field::authorization];
  if (!header.empty()) {
    *who = options.authorize(std::string_view(header.data(), header.size()));
  } else if (const auto cookie = request[http::field::cookie]; !cookie.empty()) {
    const std::optional<std::string> token =
        TokenFromCookies(std::string_view(cookie.data(), cookie.size()));
    if (token.has_value()) *who = options.authorize("Bearer " + *token);
  }
  if (*who != nullptr) return std::nullopt;
  return unauthorized(
      "unauthorized: send 'Authorization: Bearer <token>' (a browser: open "
      "/login?token=<token>)\n");
}

HttpResponse HttpServer::State::Answer(const HttpRequest& request) {
  const auto raw_target = request.target();
  const std::string_view target(raw_target.data(), raw_target.size());
  const std::string_view path = target.substr(0, target.find('?'));
  const unsigned version = request.version() == 10 ? 10 : 11;
  auto plain = [version](http::status status, std::string body) {
    http::response<http::string_body> response{status, version};
    response.set(http::field::content_type, "text/plain; charset=utf-8");
    response.body() = std::move(body);
    return response;
  };
  if (path != kMetricsPath) {
    return plain(http::status::not_found, "not found: bgkmapd serves GET /metrics only\n");
  }
  if (request.method() != http::verb::get) {
    http::response<http::string_body> response =
        plain(http::status::method_not_allowed, "method not allowed: use GET\n");
    response.set(http::field::allow, "GET");
    return response;
  }
  std::string body;
  try {
    body = render();
  } catch (const std::exception& e) {
    spdlog::error("event=metrics_render_failed reason=\"{}\"", e.what());
    return plain(http::status::internal_server_error, "cannot collect the metrics\n");
  }
  http::response<http::string_body> response{http::status::ok, version};
  response.set(http::field::content_type, kMetricsContentType);
  response.body() = std::move(body);
  return response;
}

HttpServer::HttpServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

HttpServer::~HttpServer() { Stop(); }

Result<std::unique_ptr<HttpServer>> HttpServer::Listen(const std::string& address, Render render,
                                                       Options options) {
  Result<HostPort> parsed = ParseHostPort(address);
  if (!parsed.ok()) return parsed.status();
  auto state = std::make_unique<State>(std::move(render), options);
  beast::error_code ec;
  tcp::resolver resolver(state->io);
  const tcp::resolver::results_type endpoints =
      resolver.resolve(parsed->host, std::to_string(parsed->port),
                       tcp::resolver::numeric_service | tcp::resolver::passive, ec);
  if (ec || endpoints.empty()) {
    return Status::FailedPrecondition("cannot resolve '" + parsed->host +
                                      "': " + (ec ? ec.message() : "no address"));
  }
  const tcp::endpoint endpoint = endpoints.begin()->endpoint();
  tcp::acceptor& acceptor = state->acceptor;
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return Status::FailedPrecondition("cannot listen on '" + address + "': " + ec.message());
  }
  state->port = acceptor.local_endpoint(ec).port();
  if (ec) return Status::FailedPrecondition("cannot listen on '" + address + "': " + ec.message());
  return std::unique_ptr<HttpServer>(new HttpServer(std::move(state)));
}

int HttpServer::port() const { return state_->port; }

void HttpServer::Start() {
  std::lock_guard lock(state_->stop_mu);
  if (state_->started || state_->stopped) return;
  state_->started = true;
  state_->Accept();
  state_->thread = std::thread([s = state_.get()] {
    for (;;) {
      try {
        s->io.run();
        return;
      } catch (const std::exception& e) {  // out of memory in a handler, say: keep serving
        spdlog::error("event=metrics_handler_failed reason=\"{}\"", e.what());
      }
    }
  });
}

void HttpServer::Stop() {
  std::lock_guard lock(state_->stop_mu);
  if (state_->stopped) return;
  state_->stopped = true;
  if (state_->thread.joinable()) {
    // After a render in progress; the aborted handlers left behind are dropped with the
    // io_context, their sockets already closed.
    asio::post(state_->io, [s = state_.get()] { s->CloseAll(); });
    state_->thread.join();
  } else {
    beast::error_code ignored;
    state_->acceptor.close(ignored);
  }
}

}  // namespace bgkmap
