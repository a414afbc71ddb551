#include "foxglove/foxglove_server.h"

#include <spdlog/spdlog.h>

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
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "bgkmap/server/host_port.h"
#include "foxglove/live_feed.h"
#include "foxglove/messages.h"
#include "foxglove/session.h"

namespace bgkmap::foxglove {

namespace asio = boost::asio;
namespace beast = boost::beast;
using tcp = asio::ip::tcp;

FoxgloveServer::State::State(Options o, std::shared_ptr<LiveFeed> f)
    : options(std::move(o)), feed(std::move(f)), channels(Channels()) {}

void FoxgloveServer::State::Accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor.is_open()) return;
    if (ec) {
      // Out of descriptors, say: try again shortly rather than spin.
      spdlog::warn("event=foxglove_accept_failed reason=\"{}\"", ec.message());
      retry.expires_after(std::chrono::milliseconds(100));
      retry.async_wait([this](beast::error_code timer_ec) {
        if (!timer_ec) Accept();
      });
      return;
    }
    // Connections still in their upgrade are bounded by the handshake timeout and by this.
    if (connections.size() >= options.max_clients + kMaxPendingUpgrades) {
      beast::error_code ignored;
      socket.close(ignored);
    } else if (options.tls != nullptr) {
      std::make_shared<Session<beast::ssl_stream<beast::tcp_stream>>>(*this, std::move(socket),
                                                                      *options.tls)
          ->Open();
    } else {
      std::make_shared<Session<beast::tcp_stream>>(*this, std::move(socket))->Open();
    }
    Accept();
  });
}

void FoxgloveServer::State::CheckRevocations() {
  revocations.expires_after(kRevocationCheck);
  revocations.async_wait([this](beast::error_code ec) {
    if (ec || !acceptor.is_open()) return;
    // (CloseIfRevoked may close, and so erase, the session.)
    for (SessionBase* s : std::set<SessionBase*>(connections)) s->CloseIfRevoked();
    CheckRevocations();
  });
}

void FoxgloveServer::State::CloseAll() {
  beast::error_code ignored;
  acceptor.close(ignored);
  retry.cancel();
  revocations.cancel();
  for (SessionBase* s : std::set<SessionBase*>(connections)) s->Close();
  io.stop();
}

FoxgloveServer::FoxgloveServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

FoxgloveServer::~FoxgloveServer() { Stop(); }

Result<std::unique_ptr<FoxgloveServer>> FoxgloveServer::Listen(const std::string& address,
                                                               MapPort& map, WatchHub& hub,
                                                               LatestScans& scans,
                                                               asio::thread_pool& pool,
                                                               Options options) {
  Result<HostPort> parsed = ParseHostPort(address);
  if (!parsed.ok()) return parsed.status();
  auto feed = std::make_shared<LiveFeed>(map, hub, scans, pool, options.region, options.layers);
  auto state = std::make_unique<State>(std::move(options), std::move(feed));
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
  if (!ec) state->port = acceptor.local_endpoint(ec).port();
  if (ec) {
    return Status::FailedPrecondition("cannot listen on '" + address + "': " + ec.message());
  }
  return std::unique_ptr<FoxgloveServer>(new FoxgloveServer(std::move(state)));
}

int FoxgloveServer::port() const { return state_->port; }

size_t FoxgloveServer::client_count() const { return state_->clients.load(); }

void FoxgloveServer::Start() {
  std::lock_guard lock(state_->stop_mu);
  if (state_->started || state_->stopped) return;
  state_->started = true;
  state_->feed->Start();
  state_->Accept();
  if (state_->options.tokens != nullptr) state_->CheckRevocations();
  state_->thread = std::thread([s = state_.get()] {
    for (;;) {
      try {
        s->io.run();
        return;
      } catch (const std::exception& e) {  // out of memory in a handler, say: keep serving
        spdlog::error("event=foxglove_handler_failed reason=\"{}\"", e.what());
      }
    }
  });
}

void FoxgloveServer::Stop() {
  std::lock_guard lock(state_->stop_mu);
  if (state_->stopped) return;
  state_->stopped = true;
  state_->feed->Stop();
  if (state_->thread.joinable()) {
    asio::post(state_->io, [s = state_.get()] { s->CloseAll(); });
    state_->thread.join();
  } else {
    beast::error_code ignored;
    state_->acceptor.close(ignored);
  }
}

}  // namespace bgkmap::foxglove
