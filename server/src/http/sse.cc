#include "http/sse.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/post.hpp>
#include <climits>
#include <nlohmann/json.hpp>
#include <vector>

namespace bgkmap {
namespace {

constexpr size_t kMaxTilesPerEvent = 4096;
// How often the streams are checked for a revoked token (as the gRPC streams' watchdog).
constexpr std::chrono::seconds kRevocationCheck{1};

std::string EventText(std::string_view name, const nlohmann::json& data) {
  return "event: " + std::string(name) + "\ndata: " + data.dump() + "\n\n";
}

}  // namespace

struct EventStreams::Session {
  // Takes one of `who`'s event stream slots (none without tokens: null usage); `admitted` says
  // whether there was one.
  Session(std::shared_ptr<HttpExchange> e, PrincipalRef w) : out(std::move(e)), who(std::move(w)) {
    if (who->usage != nullptr && who->usage->event_streams.fetch_add(1) >= who->max_event_streams) {
      who->usage->event_streams.fetch_sub(1);
      admitted = false;
    }
  }
  ~Session() {
    if (admitted && who->usage != nullptr) who->usage->event_streams.fetch_sub(1);
  }
  const std::shared_ptr<HttpExchange> out;
  const PrincipalRef who;
  bool admitted = true;
  std::atomic<uint64_t> hub_id{0};
  std::atomic<bool> flush_posted{false};
};

EventStreams::EventStreams(MapPort& map, WatchHub& hub, boost::asio::thread_pool& pool,
                           size_t max_clients, std::chrono::milliseconds ping_period)
    : map_(map), hub_(hub), pool_(pool), max_clients_(max_clients), ping_period_(ping_period) {
  pinger_ = std::thread([this] { Ping(); });
}

EventStreams::~EventStreams() { Stop(); }

void EventStreams::Open(const HttpRequest& request, PrincipalRef who,
                        std::shared_ptr<HttpExchange> exchange) {
  auto session = std::make_shared<Session>(std::move(exchange), std::move(who));
  if (!session->admitted) {
    const Principal& p = *session->who;
    HttpResponse many{boost::beast::http::status::too_many_requests, request.version()};
    many.set(boost::beast::http::field::content_type, "text/plain; charset=utf-8");
    many.set(boost::beast::http::field::retry_after, "5");
    many.body() = "token '" + p.name + "' already holds its limit of " +
                  std::to_string(p.max_event_streams) +
                  " open event streams (server.auth.max_event_streams_per_token or the token's "
                  "own limit); retry later\n";
    session->out->Reply(std::move(many));
    return;
  }
  std::unique_lock lock(mu_);
  if (stopped_ || sessions_.size() >= max_clients_) {
    lock.unlock();
    HttpResponse busy{boost::beast::http::status::service_unavailable, request.version()};
    busy.set(boost::beast::http::field::content_type, "text/plain; charset=utf-8");
    busy.set(boost::beast::http::field::retry_after, "5");
    busy.body() = stopped_ ? "shutting down\n"
                           : "too many event streams (" + std::to_string(max_clients_) +
                                 " open); retry later\n";
    session->out->Reply(std::move(busy));
    return;
  }
  const uint64_t key = next_key_++;
  sessions_[key] = session;
  lock.unlock();

  std::weak_ptr<Session> weak = session;
  const uint64_t hello_version = map_.known_version();
  session->out->StartStream(
      "HTTP/1.1 200 OK\r\nServer: bgkmapd\r\nContent-Type: text/event-stream\r\n"
      "Cache-Control: no-cache\r\nX-Accel-Buffering: no\r\nConnection: close\r\n\r\n"
      "retry: 1000\n\n" +
          EventText("hello", {{"map_version", hello_version}}),
      [this, key] { Remove(key); });
  // The whole map: a key range no tile lies outside of.
  const uint64_t id = hub_.Subscribe({INT_MIN, INT_MIN}, {INT_MAX, INT_MAX},
                                     [this, weak] {
                                       std::shared_ptr<Session> s = weak.lock();
                                       if (s && !s->flush_posted.exchange(true)) {
                                         boost::asio::post(pool_, [this, s] { Flush(s); });
                                       }
                                     },
                                     {});
  session->hub_id = id;
  lock.lock();
  if (sessions_.count(key) == 0) {  // closed meanwhile
    lock.unlock();
    hub_.Unsubscribe(id);
    return;
  }
  const size_t clients = sessions_.size();
  lock.unlock();
  // A change between the hello and the subscription reached no one: a second hello with the newer
  // version tells the page to reload what it shows (as after a reconnection).
  if (const uint64_t now = map_.known_version(); now != hello_version) {
    session->out->Send(EventText("hello", {{"map_version", now}}));
  }
  spdlog::debug("event=web_events_open clients={}", clients);
}

void EventStreams::Flush(const std::shared_ptr<Session>& s) {
  s->flush_posted = false;
  const uint64_t id = s->hub_id.load();
  if (id == 0) return;
  const double res = map_.geometry().resolution();
  const int n = map_.geometry().tile_size();
  for (;;) {
    nlohmann::json tiles = nlohmann::json::array();
    TileKey k;
    while (tiles.size() < kMaxTilesPerEvent && hub_.Take(id, &k)) {
      // The tile's extent in metres: [x0, y0, x1, y1].
      tiles.push_back({k.x * n * res, k.y * n * res, (k.x + 1) * n * res, (k.y + 1) * n * res});
    }
    if (tiles.empty()) return;
    // Watchers are told after a change counts as applied: this version covers it.
    const nlohmann::json data = {{"map_version", map_.known_version()}, {"tiles", tiles}};
    if (!s->out->Send(EventText("tiles", data))) return;  // closed: on_close removes it
  }
}

void EventStreams::Remove(uint64_t key) {
  std::shared_ptr<Session> s;
  {
    std::lock_guard lock(mu_);
    auto it = sessions_.find(key);
    if (it == sessions_.end()) return;
    s = std::move(it->second);
    sessions_.erase(it);
  }
  if (const uint64_t id = s->hub_id.load(); id != 0) hub_.Unsubscribe(id);
}

void EventStreams::Ping() {
  using Clock = std::chrono::steady_clock;
  std::unique_lock lock(mu_);
  Clock::time_point next_ping = Clock::now() + ping_period_;
  while (!stopped_) {
    cv_.wait_until(lock, std::min(next_ping, Clock::now() + kRevocationCheck));
    if (stopped_) return;
    std::vector<std::shared_ptr<Session>> revoked;
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      if (it->second->who->Revoked()) {
        revoked.push_back(std::move(it->second));
        it = sessions_.erase(it);
      } else {
        ++it;
      }
    }
    if (Clock::now() >= next_ping) {
      // A comment line: browsers ignore it; a peer that went away fails the write.
      for (auto& [key, s] : sessions_) s->out->Send(": ping\n\n");
      next_ping = Clock::now() + ping_period_;
    }
    if (revoked.empty()) continue;
    lock.unlock();  // the hub is not called under mu_ (its callbacks do not take it, Remove does)
    for (const std::shared_ptr<Session>& s : revoked) {
      if (const uint64_t id = s->hub_id.load(); id != 0) hub_.Unsubscribe(id);
      spdlog::info("event=web_events_revoked token=\"{}\"", s->who->name);
      s->out->Close();
    }
    lock.lock();
  }
}

void EventStreams::Stop() {
  std::map<uint64_t, std::shared_ptr<Session>> sessions;
  {
    std::lock_guard lock(mu_);
    if (stopped_) return;
    stopped_ = true;
    sessions.swap(sessions_);
  }
  cv_.notify_all();
  if (pinger_.joinable()) pinger_.join();
  for (auto& [key, s] : sessions) {
    if (const uint64_t id = s->hub_id.load(); id != 0) hub_.Unsubscribe(id);
    s->out->Close();
  }
}

size_t EventStreams::count() const {
  std::lock_guard lock(mu_);
  return sessions_.size();
}

}  // namespace bgkmap
