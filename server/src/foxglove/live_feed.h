// What the Foxglove port sends, produced once for every client: the map's Grid over the
// configured region, read through the map port again whenever the watch hub says a tile of the
// region changed (changes arriving meanwhile coalesce into one read), and the robots'
// transforms and last scans whenever LatestScans records one. Each message is encoded once and
// handed to every client (a SessionSink), which frames it for its own subscriptions.
#pragma once

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "serving/latest_scans.h"
#include "serving/map_port.h"
#include "serving/watch_hub.h"

namespace bgkmap::foxglove {

// A client of the port, as the feed sees it. Deliver may be called from any thread and must
// not block; the client sends the message to each of its subscriptions of `channel`.
class SessionSink {
 public:
  virtual ~SessionSink() = default;
  virtual void Deliver(uint32_t channel, uint64_t time_ns,
                       std::shared_ptr<const std::string> message) = 0;
  // A problem the client should know of (a region it cannot be sent), as a status message.
  virtual void Warn(const std::string& message) = 0;
};

class LiveFeed : public std::enable_shared_from_this<LiveFeed> {
 public:
  // `region`: the Grid's cells; `layers`: its fields. Work runs on `pool`.
  LiveFeed(MapPort& map, WatchHub& hub, LatestScans& scans, boost::asio::thread_pool& pool,
           CellBox region, std::vector<Layer> layers);

  // Subscribes to the hub and to LatestScans. Stop() unsubscribes; idempotent.
  void Start();
  void Stop();

  void Add(const std::shared_ptr<SessionSink>& sink);
  void Remove(const SessionSink* sink);
  // `sink` subscribed to `channel`: it is sent the channel's current message(s) (the region's
  // grid, every robot's transform, every robot's last scan), on the pool.
  void SendCurrent(const std::shared_ptr<SessionSink>& sink, uint32_t channel);

 private:
  std::vector<std::shared_ptr<SessionSink>> Sinks() const;
  // Reads the region and sends the grid to `to` (every sink when null).
  void SendGrid(const std::shared_ptr<SessionSink>& to);
  void SendRobot(const std::string& robot_id);

  MapPort& map_;
  WatchHub& hub_;
  LatestScans& scans_;
  boost::asio::thread_pool& pool_;
  const CellBox region_;
  const std::vector<Layer> layers_;

  mutable std::mutex mu_;
  std::map<const SessionSink*, std::weak_ptr<SessionSink>> sinks_;
  uint64_t hub_id_ = 0;
  uint64_t scans_id_ = 0;
  bool stopped_ = false;
  std::atomic<bool> grid_posted_{false};
  // Held while a grid (or a robot's messages) is read and handed out, so that clients receive
  // them in the order they were read: an older grid never follows a newer one.
  std::mutex grid_order_;
  std::mutex robot_order_;
};

}  // namespace bgkmap::foxglove
