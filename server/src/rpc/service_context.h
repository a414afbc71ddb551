// What every RPC handler shares: the served map, the watch hub, the worker pools, the limits,
// and the registry of long-lived streams that a shutdown has to drain.
#pragma once

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <cstdint>
#include <mutex>
#include <unordered_map>

#include "bgkmap/server/server_config.h"
#include "serving/served_map.h"
#include "serving/watch_hub.h"

namespace bgkmap {

// A long-lived stream that must wind down when the server stops.
class DrainListener {
 public:
  // Stop taking new work, finish and answer what was taken, then end the call.
  virtual void BeginDrain() = 0;

 protected:
  ~DrainListener() = default;
};

class SessionRegistry {
 public:
  enum class Kind { kIngest, kWatch };
  enum class Admit { kOk, kDraining, kFull };

  Admit Add(DrainListener* session, Kind kind, uint32_t limit);
  void Remove(DrainListener* session);
  // Marks the registry draining and calls BeginDrain() on every open session.
  void DrainAll();
  bool draining() const;
  size_t count(Kind kind) const;

 private:
  mutable std::mutex mu_;
  bool draining_ = false;
  std::unordered_map<DrainListener*, Kind> sessions_;
};

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
  ServiceContext(const ServerConfig& cfg, ServedMap& served_map, WatchHub& watch_hub,
                 boost::asio::thread_pool& ingest, boost::asio::thread_pool& query)
      : config(cfg),
        limits(cfg.limits),
        map(served_map),
        hub(watch_hub),
        ingest_pool(ingest),
        query_pool(query) {}

  const ServerConfig config;
  const ServerLimits limits;
  ServedMap& map;
  WatchHub& hub;
  boost::asio::thread_pool& ingest_pool;  // scan preparation (changes run there too)
  boost::asio::thread_pool& query_pool;   // queries, watch updates, import and export I/O
  SessionRegistry sessions;
  std::atomic<uint32_t> queries{0};      // concurrent queries
  std::atomic<uint32_t> unary_scans{0};  // concurrent IngestScan calls
  std::atomic<uint32_t> imports{0};      // ImportMap calls (one at a time)
  ByteBudget region_bytes{limits.max_region_bytes_in_flight};
};

}  // namespace bgkmap
