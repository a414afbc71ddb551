#include "http/metrics_http.h"

#include <spdlog/spdlog.h>

#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>
#include <exception>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "host_port.h"

namespace bgkmap {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

constexpr const char* kMetricsPath = "/metrics";
constexpr const char* kMetricsContentType = "text/plain; version=0.0.4; charset=utf-8";
// How long, and for how many bytes, a connection waits for the client to close after the
// response.
constexpr std::chrono::seconds kLingerTime{1};
constexpr size_t kMaxLingerBytes = 1 << 20;

class ConnectionBase {
 public:
  virtual void Close() = 0;

 protected:
  ~ConnectionBase() = default;
};

}  // namespace

struct MetricsHttpServer::State {
  State(Render r, Options o) : render(std::move(r)), options(o) {}

  void Accept();
  // Answers a parsed request: the status and body.
  http::response<http::string_body> Answer(const http::request<http::string_body>& request);

  // Closes the listener and every connection, then stops the loop. On the io thread.
  void CloseAll();

  const Render render;
  const Options options;
  // The open connections, touched on the io thread only. Declared before the io_context: its
  // destruction destroys the handlers still pending, and with them connections, which remove
  // themselves from here.
  std::set<ConnectionBase*> connections;
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

// One client connection: read one request (bounded in time and size), answer it, close.
// `Stream` is beast::tcp_stream, or beast::ssl_stream of one (then the TLS handshake first).
template <typename Stream>
class Connection final : public ConnectionBase,
                         public std::enable_shared_from_this<Connection<Stream>> {
 public:
  using State = MetricsHttpServer::State;
  static constexpr bool kTls = !std::is_same_v<Stream, beast::tcp_stream>;

  template <typename... StreamArgs>
  Connection(State& state, StreamArgs&&... stream_args)
      : stream_(std::forward<StreamArgs>(stream_args)...),
        buffer_(state.options.max_request_bytes),
        state_(state) {
    state_.connections.insert(this);
    parser_.header_limit(static_cast<uint32_t>(state.options.max_request_bytes));
    parser_.body_limit(state.options.max_request_bytes);
  }
  ~Connection() { state_.connections.erase(this); }

  void Open() {
    if constexpr (kTls) {
      Tcp().expires_after(state_.options.read_timeout);
      stream_.async_handshake(
          asio::ssl::stream_base::server, [self = this->shared_from_this()](beast::error_code ec) {
            if (ec) {
              spdlog::debug("event=metrics_tls_failed reason=\"{}\"", ec.message());
              return;
            }
            self->Read();
          });
    } else {
      Read();
    }
  }

  void Read() {
    Tcp().expires_after(state_.options.read_timeout);
    http::async_read(
        stream_, buffer_, parser_,
        [self = this->shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  // Aborts whatever is pending; the handlers then release the connection.
  void Close() override { Tcp().close(); }

 private:
  void OnRead(beast::error_code ec) {
    if (ec == beast::error::timeout || ec == http::error::end_of_stream ||
        ec == http::error::partial_message || ec == asio::error::operation_aborted ||
        ec == asio::error::eof || ec == asio::error::connection_reset) {
      return;  // closed or too slow: nothing to answer
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
      Write(std::move(response));
      return;
    }
    Write(state_.Answer(parser_.get()));
  }

  void Write(http::response<http::string_body> response) {
    response.set(http::field::server, "bgkmapd");
    if (response[http::field::content_type].empty()) {
      response.set(http::field::content_type, "text/plain; charset=utf-8");
    }
    response.keep_alive(false);
    response.prepare_payload();
    response_ = std::move(response);
    Tcp().expires_after(state_.options.read_timeout);
    http::async_write(stream_, *response_,
                      [self = this->shared_from_this()](beast::error_code write_ec, size_t) {
                        if (write_ec) return;
                        self->CloseSend();
                      });
  }

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
  http::request_parser<http::string_body> parser_;
  std::optional<http::response<http::string_body>> response_;
  std::array<char, 4096> discard_;
  size_t drained_ = 0;
  State& state_;
};

}  // namespace

void MetricsHttpServer::State::Accept() {
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
      beast::error_code ignored;
      socket.close(ignored);  // a scraper retries at its next interval
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

void MetricsHttpServer::State::CloseAll() {
  beast::error_code ignored;
  acceptor.close(ignored);
  retry.cancel();
  // Close() only aborts operations; the connections go when their handlers have run.
  for (ConnectionBase* c : connections) c->Close();
  io.stop();
}

http::response<http::string_body> MetricsHttpServer::State::Answer(
    const http::request<http::string_body>& request) {
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
  if (options.authorize != nullptr) {
    const auto header = request[http::field::authorization];
    if (!options.authorize(std::string_view(header.data(), header.size()))) {
      http::response<http::string_body> response =
          plain(http::status::unauthorized, "unauthorized: send 'Authorization: Bearer <token>'\n");
      response.set(http::field::www_authenticate, "Bearer");
      return response;
    }
  }
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

MetricsHttpServer::MetricsHttpServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

MetricsHttpServer::~MetricsHttpServer() { Stop(); }

Result<std::unique_ptr<MetricsHttpServer>> MetricsHttpServer::Listen(const std::string& address,
                                                                     Render render,
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
  return std::unique_ptr<MetricsHttpServer>(new MetricsHttpServer(std::move(state)));
}

int MetricsHttpServer::port() const { return state_->port; }

void MetricsHttpServer::Start() {
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

void MetricsHttpServer::Stop() {
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
