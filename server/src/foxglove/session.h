// Inside the Foxglove port (foxglove_server.cc): the server's state on its io thread and one
// client's session, plain or TLS. Not for other rooms.
#pragma once

#include <spdlog/spdlog.h>

#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "foxglove/foxglove_server.h"
#include "foxglove/live_feed.h"
#include "foxglove/messages.h"
#include "foxglove/outgoing_queue.h"
#include "foxglove/protocol.h"
#include "foxglove/upgrade_check.h"

namespace bgkmap::foxglove {

// Connections accepted beyond max_clients while their upgrade is read (each one is refused
// or admitted within the handshake timeout).
inline constexpr size_t kMaxPendingUpgrades = 16;
// Subscriptions one client may hold (three channels; a viewer subscribes once to each).
inline constexpr size_t kMaxSubscriptions = 64;

// How often the sessions are checked for a revoked token (as gRPC's streams and /events).
inline constexpr std::chrono::milliseconds kRevocationCheck{250};

class SessionBase {
 public:
  virtual void Close() = 0;  // on the io thread
  // Closes the session if a tokens-file reload revoked its token (on the io thread).
  virtual void CloseIfRevoked() = 0;

 protected:
  ~SessionBase() = default;
};

struct FoxgloveServer::State {
  State(Options o, std::shared_ptr<LiveFeed> f);
  void Accept();
  void CloseAll();  // on the io thread
  // Every kRevocationCheck: closes the sessions of revoked tokens (issue 25).
  void CheckRevocations();

  const Options options;
  const std::shared_ptr<LiveFeed> feed;
  const std::vector<Channel> channels;
  std::set<SessionBase*> connections;  // on the io thread
  std::atomic<size_t> clients{0};      // upgraded connections
  uint64_t next_session = 1;
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor acceptor{io};
  boost::asio::steady_timer retry{io};
  boost::asio::steady_timer revocations{io};
  int port = 0;
  std::thread thread;
  std::mutex stop_mu;
  bool started = false;
  bool stopped = false;
};

// One client: the TLS handshake (with TLS), the HTTP upgrade request and its checks, then the
// protocol. Lives on the io thread; Deliver and Warn post there from any thread.
template <typename Stream>
class Session final : public SessionBase,
                      public SessionSink,
                      public std::enable_shared_from_this<Session<Stream>> {
 public:
  using State = FoxgloveServer::State;
  static constexpr bool kTls = !std::is_same_v<Stream, boost::beast::tcp_stream>;

  template <typename... StreamArgs>
  explicit Session(State& state, StreamArgs&&... stream_args)
      : ws_(std::forward<StreamArgs>(stream_args)...),
        executor_(ws_.get_executor()),
        state_(state),
        id_(state.next_session++) {
    state_.connections.insert(this);
  }
  ~Session() override {
    state_.connections.erase(this);
    if (upgraded_) --state_.clients;
  }

  void Open() {
    Tcp().expires_after(state_.options.handshake_timeout);
    if constexpr (kTls) {
      ws_.next_layer().async_handshake(
          boost::asio::ssl::stream_base::server,
          [self = this->shared_from_this()](boost::beast::error_code ec) {
            if (ec) {
              spdlog::debug("event=foxglove_tls_failed reason=\"{}\"", ec.message());
              return;
            }
            self->ReadUpgrade();
          });
    } else {
      ReadUpgrade();
    }
  }

  void Close() override {
    if (closed_) return;
    closed_ = true;
    state_.connections.erase(this);
    state_.feed->Remove(this);
    boost::beast::error_code ignored;
    Tcp().socket().close(ignored);
  }

  // A revoked token's viewer is told why in the WebSocket's close frame (policy violation), then
  // its connection closes; the close handshake is bounded by the stream's timeout.
  void CloseIfRevoked() override {
    if (closed_ || revoked_ || who_ == nullptr || !who_->Revoked()) return;
    revoked_ = true;
    spdlog::info("event=foxglove_client_revoked session={} token=\"{}\"", id_, who_->name);
    state_.feed->Remove(this);
    if (!ws_.is_open()) {
      Close();
      return;
    }
    namespace websocket = boost::beast::websocket;
    // A close frame's reason holds at most 123 bytes.
    std::string reason = "token '" + who_->name + "' revoked";
    if (reason.size() > 123) reason = "token revoked";
    ws_.async_close(websocket::close_reason(websocket::close_code::policy_error, reason),
                    [self = this->shared_from_this()](Beast) { self->Close(); });
  }

  void Deliver(uint32_t channel, uint64_t time_ns,
               std::shared_ptr<const std::string> message) override {
    boost::asio::post(executor_, [weak = this->weak_from_this(), channel, time_ns, message] {
      if (auto self = weak.lock()) self->Send(channel, time_ns, *message);
    });
  }
  void Warn(const std::string& message) override {
    boost::asio::post(executor_, [weak = this->weak_from_this(), message] {
      if (auto self = weak.lock()) self->SendStatus(StatusLevel::kWarning, message);
    });
  }

 private:
  using Beast = boost::beast::error_code;
  boost::beast::tcp_stream& Tcp() { return boost::beast::get_lowest_layer(ws_); }

  void ReadUpgrade() {
    namespace http = boost::beast::http;
    parser_.emplace();
    parser_->header_limit(static_cast<uint32_t>(state_.options.max_request_bytes));
    parser_->body_limit(state_.options.max_request_bytes);
    http::async_read(ws_.next_layer(), buffer_, *parser_,
                     [self = this->shared_from_this()](Beast ec, size_t) {
                       if (!ec) self->OnUpgradeRequest();
                     });
  }

  void OnUpgradeRequest() {
    namespace http = boost::beast::http;
    namespace websocket = boost::beast::websocket;
    const http::request<http::string_body>& request = parser_->get();
    auto view = [](boost::beast::string_view s) { return std::string_view(s.data(), s.size()); };
    const UpgradeRequest checked{websocket::is_upgrade(request),
                                 view(request[http::field::sec_websocket_protocol]),
                                 view(request[http::field::authorization]), view(request.target())};
    if (std::optional<Refusal> refusal =
            CheckUpgrade(checked, state_.options.tokens, state_.clients.load(),
                         state_.options.max_clients, &who_)) {
      spdlog::info("event=foxglove_refused status={} reason=\"{}\"", refusal->status,
                   refusal->reason);
      Refuse(*refusal, request.version());
      return;
    }
    upgraded_ = true;
    ++state_.clients;
    Tcp().expires_never();  // the WebSocket's own timeouts from here on
    ws_.set_option(websocket::stream_base::timeout{state_.options.handshake_timeout,
                                                   state_.options.idle_timeout, true});
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& response) {
      response.set(http::field::sec_websocket_protocol, kSubprotocol);
      response.set(http::field::server, "bgkmapd");
    }));
    ws_.read_message_max(state_.options.max_message_bytes);
    ws_.async_accept(request, [self = this->shared_from_this()](Beast ec) {
      if (ec) {
        self->Close();
        return;
      }
      self->OnOpen();
    });
  }

  void Refuse(const Refusal& refusal, unsigned version) {
    namespace http = boost::beast::http;
    response_.emplace(static_cast<http::status>(refusal.status), version);
    response_->set(http::field::server, "bgkmapd");
    response_->set(http::field::content_type, "text/plain; charset=utf-8");
    if (refusal.status == 401) response_->set(http::field::www_authenticate, "Bearer");
    if (refusal.status == 503) response_->set(http::field::retry_after, "5");
    response_->body() = refusal.reason + "\n";
    response_->keep_alive(false);
    response_->prepare_payload();
    http::async_write(ws_.next_layer(), *response_,
                      [self = this->shared_from_this()](Beast, size_t) { self->Close(); });
  }

  void OnOpen() {
    spdlog::info("event=foxglove_client_open session={} clients={}", id_, state_.clients.load());
    state_.feed->Add(this->shared_from_this());
    Queue({std::make_shared<const std::string>(ServerInfoJson("bgkmapd", std::to_string(id_))),
           false, std::nullopt});
    Queue(
        {std::make_shared<const std::string>(AdvertiseJson(state_.channels)), false, std::nullopt});
    Read();
  }

  void Read() {
    ws_.async_read(read_buffer_, [self = this->shared_from_this()](Beast ec, size_t) {
      if (ec) {
        spdlog::info("event=foxglove_client_closed session={} reason=\"{}\"", self->id_,
                     ec.message());
        self->Close();
        return;
      }
      if (self->ws_.got_text()) {
        self->Handle(boost::beast::buffers_to_string(self->read_buffer_.data()));
      } else {
        self->SendStatus(StatusLevel::kError,
                         "binary client messages (publishing, services) are not offered: "
                         "bgkmapd's channels are read-only");
      }
      self->read_buffer_.consume(self->read_buffer_.size());
      self->Read();
    });
  }

  void Handle(const std::string& text) {
    ClientMessage message = ParseClientMessage(text);
    switch (message.op) {
      case ClientMessage::Op::kInvalid:
        SendStatus(StatusLevel::kError, message.error);
        return;
      case ClientMessage::Op::kSubscribe:
        for (const Subscription& s : message.subscribe) Subscribe(s);
        return;
      case ClientMessage::Op::kUnsubscribe:
        for (uint32_t id : message.unsubscribe) {
          if (subscriptions_.erase(id) == 0) {
            SendStatus(StatusLevel::kError,
                       "unsubscribe: subscription " + std::to_string(id) + " is not open");
          }
        }
        return;
    }
  }

  void Subscribe(const Subscription& s) {
    bool known = false;
    std::string offered;
    for (const Channel& c : state_.channels) {
      known = known || c.id == s.channel_id;
      offered += (offered.empty() ? "" : ", ") + std::to_string(c.id) + " " + c.topic;
    }
    std::string error;
    if (!known) {
      error = "subscribe: channel " + std::to_string(s.channel_id) +
              " is not advertised (channels: " + offered + ")";
    } else if (subscriptions_.count(s.id) != 0) {
      error = "subscribe: subscription id " + std::to_string(s.id) + " is already in use";
    } else if (subscriptions_.size() >= kMaxSubscriptions) {
      error = "subscribe: at most " + std::to_string(kMaxSubscriptions) + " subscriptions";
    }
    if (!error.empty()) {
      SendStatus(StatusLevel::kError, error);
      return;
    }
    subscriptions_[s.id] = s.channel_id;
    state_.feed->SendCurrent(this->shared_from_this(), s.channel_id);
  }

  void Send(uint32_t channel, uint64_t time_ns, const std::string& message) {
    for (const auto& [id, subscribed] : subscriptions_) {
      if (subscribed != channel) continue;
      auto frame = std::make_shared<const std::string>(MessageDataFrame(id, time_ns, message));
      Queue({std::move(frame), true,
             channel == kGridChannel ? std::optional<uint32_t>(id) : std::nullopt});
    }
  }

  void SendStatus(StatusLevel level, const std::string& message) {
    Queue({std::make_shared<const std::string>(StatusJson(level, message)), false, std::nullopt});
  }

  // Sends in order (OutgoingQueue); a client too slow for the bound is dropped, not buffered for.
  void Queue(OutgoingQueue::Frame frame) {
    if (closed_ || revoked_) return;
    if (!queue_.Add(std::move(frame))) {
      spdlog::warn("event=foxglove_slow_client_dropped session={} queued_bytes={}", id_,
                   queue_.queued_bytes());
      Close();
      return;
    }
    WriteNext();
  }

  void WriteNext() {
    if (closed_ || revoked_) return;
    const OutgoingQueue::Frame* frame = queue_.StartWrite();
    if (frame == nullptr) return;
    ws_.binary(frame->binary);
    ws_.async_write(boost::asio::buffer(*frame->bytes),
                    [self = this->shared_from_this()](Beast ec, size_t) {
                      if (ec) {
                        self->Close();
                        return;
                      }
                      self->queue_.FinishWrite();
                      self->WriteNext();
                    });
  }

  boost::beast::websocket::stream<Stream> ws_;
  const boost::asio::any_io_executor executor_;
  State& state_;
  const uint64_t id_;
  boost::beast::flat_buffer buffer_;
  boost::beast::flat_buffer read_buffer_;
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;
  std::optional<boost::beast::http::response<boost::beast::http::string_body>> response_;
  PrincipalRef who_;  // the token it was admitted with (null without tokens)
  bool upgraded_ = false;
  bool closed_ = false;
  bool revoked_ = false;                        // closing: its token was revoked
  std::map<uint32_t, uint32_t> subscriptions_;  // subscription id -> channel
  OutgoingQueue queue_{state_.options.max_queued_bytes};
};

}  // namespace bgkmap::foxglove
