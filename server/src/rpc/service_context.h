// What every RPC handler shares: the map port, the watch hub, the worker pools, the limits,
// and the registry of long-lived streams that a shutdown has to drain.
#pragma once

#include <grpcpp/support/server_callback.h>

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>

#include "auth/principal.h"
#include "bgkmap/server/latency_histogram.h"
#include "bgkmap/server/server_config.h"
#include "serving/latest_scans.h"
#include "serving/map_port.h"
#include "serving/watch_hub.h"

namespace bgkmap {

// A long-lived stream that must wind down when the server stops, and that gives its slot back
// when its client goes idle or stops reading (server.*_timeout_s).
class DrainListener {
 public:
  // Stop taking new work, finish and answer what was taken, then end the call.
  virtual void BeginDrain() = 0;
  // Called every watchdog period with the time: end the call if it has been idle or stalled
  // for too long. Must not block; called with the registry's lock held (like BeginDrain).
  virtual void Tick(std::chrono::steady_clock::time_point /*now*/) {}

 protected:
  ~DrainListener() = default;
};

class SessionRegistry {
 public:
  // kStream: region, export and watch streams watched for stalled writes (not counted).
  enum class Kind { kIngest, kWatch, kStream };
  enum class Admit { kOk, kDraining, kFull };

  SessionRegistry() = default;
  ~SessionRegistry() { StopWatchdog(); }
  SessionRegistry(const SessionRegistry&) = delete;
  SessionRegistry& operator=(const SessionRegistry&) = delete;

  Admit Add(DrainListener* session, Kind kind, uint32_t limit);
  void Remove(DrainListener* session);
  // Marks the registry draining and calls BeginDrain() on every open session.
  void DrainAll();
  bool draining() const;
  size_t count(Kind kind) const;

  // Calls Tick() on every open session now, and then every `period` on a thread of its own
  // until StopWatchdog().
  void TickAll();
  void StartWatchdog(std::chrono::milliseconds period);
  void StopWatchdog();

 private:
  mutable std::mutex mu_;
  bool draining_ = false;
  std::unordered_map<DrainListener*, Kind> sessions_;

  std::mutex watchdog_mu_;
  std::condition_variable watchdog_cv_;
  bool watchdog_stop_ = false;
  std::thread watchdog_;
};

// Cancels a streaming call whose client has stopped taking its messages: a write outstanding for
// longer than server.stalled_write_timeout_s. Without it, a client that never reads its region
// (or export, or watch) holds its query slot, its raster and its snapshot forever. A reactor
// owns one, registers it (Kind::kStream) and removes it in OnDone.
class StalledWriteWatch final : public DrainListener {
 public:
  StalledWriteWatch(grpc::CallbackServerContext* call, double timeout_s);
  void WriteStarted();                                  // just before StartWrite()
  void WriteDone();                                     // first thing in OnWriteDone()
  bool cancelled() const { return cancelled_.load(); }  // by this watch
  void BeginDrain() override {}
  void Tick(std::chrono::steady_clock::time_point now) override;

 private:
  grpc::CallbackServerContext* const call_;
  const std::chrono::steady_clock::duration timeout_;  // zero: never
  std::atomic<int64_t> write_since_{0};  // steady_clock ticks of the outstanding write; 0: none
  std::atomic<bool> cancelled_{false};
};

// server.*_timeout_s as a steady_clock duration (0: never), and as text for messages ("0.5").
std::chrono::steady_clock::duration TimeoutOf(double seconds);
std::string SecondsText(double seconds);

struct ServiceContext;
// RESOURCE_EXHAUSTED: server.max_concurrent_queries queries are running (a retry can succeed).
grpc::Status QueriesBusy(const ServiceContext& ctx);

// Bounds a counter of concurrent operations; released on destruction.
class Permit {
 public:
  Permit(std::atomic<uint32_t>& counter, uint32_t limit);
  Permit(Permit&& other) noexcept : counter_(other.counter_) { other.counter_ = nullptr; }
  Permit(const Permit&) = delete;
  Permit& operator=(const Permit&) = delete;
  ~Permit();
  explicit operator bool() const { return counter_ != nullptr; }

 private:
  std::atomic<uint32_t>* counter_;
};

// A running query's two slots: one of server.max_concurrent_queries and one of its token's
// (Principal::max_queries; none when authentication is off). Released on destruction.
class QueryPermit {
 public:
  QueryPermit(ServiceContext& ctx, const Principal& who);
  explicit operator bool() const { return refusal_.ok(); }
  // RESOURCE_EXHAUSTED naming the limit that was reached (OK when held).
  const grpc::Status& refusal() const { return refusal_; }

 private:
  std::optional<Permit> global_;
  std::optional<Permit> token_;
  grpc::Status refusal_;
};

// RESOURCE_EXHAUSTED: `who` holds its token's limit of `limit` `what` (a retry can succeed).
grpc::Status TokenQuotaReached(const Principal& who, uint32_t limit, const std::string& what,
                               const std::string& key);

// A budget of bytes shared by concurrent operations (region rasters held in memory).
class ByteBudget {
 public:
  explicit ByteBudget(uint64_t limit) : limit_(limit) {}
  bool TryAcquire(uint64_t bytes);
  void Release(uint64_t bytes) { used_.fetch_sub(bytes); }
  uint64_t limit() const { return limit_; }

 private:
  const uint64_t limit_;
  std::atomic<uint64_t> used_{0};
};

struct ServiceContext {
  ServiceContext(const ServerConfig& cfg, MapPort& port, WatchHub& watch_hub,
                 boost::asio::thread_pool& ingest, boost::asio::thread_pool& query)
      : config(cfg),
        limits(cfg.limits),
        map(port),
        hub(watch_hub),
        ingest_pool(ingest),
        query_pool(query) {}

  const ServerConfig config;
  const ServerLimits limits;
  MapPort& map;  // the single server's map or a cluster node: handlers never ask which
  WatchHub& hub;
  boost::asio::thread_pool& ingest_pool;  // scan preparation (changes run there too)
  boost::asio::thread_pool& query_pool;   // queries, watch updates, import and export I/O
  SessionRegistry sessions;
  std::atomic<uint32_t> queries{0};      // concurrent queries
  std::atomic<uint32_t> unary_scans{0};  // concurrent IngestScan calls
  std::atomic<uint32_t> imports{0};      // ImportMap calls (one at a time)
  ByteBudget region_bytes{limits.max_region_bytes_in_flight};
  // How long requests' phases take (/metrics: bgkmap_request_phase_seconds).
  RequestLatencies latencies;
  // Each robot's latest applied scan, for live views (the Foxglove port); null when none.
  LatestScans* latest_scans = nullptr;
};

// One line per admin action (event=audit): who (token name and role), what, the box or robot
// it touched, the map version it produced, and the peer.
void AuditLog(const Principal& who, const std::string& action, const std::string& details,
              uint64_t map_version, const std::string& peer);

}  // namespace bgkmap
