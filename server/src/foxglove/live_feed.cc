#include "foxglove/live_feed.h"

#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>

#include "foxglove/messages.h"

namespace bgkmap::foxglove {
namespace {

uint64_t NowNs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

}  // namespace

LiveFeed::LiveFeed(MapPort& map, WatchHub& hub, LatestScans& scans, boost::asio::thread_pool& pool,
                   CellBox region, std::vector<Layer> layers)
    : map_(map),
      hub_(hub),
      scans_(scans),
      pool_(pool),
      region_(region),
      layers_(std::move(layers)) {}

void LiveFeed::Start() {
  const GridGeometry& g = map_.geometry();
  std::weak_ptr<LiveFeed> weak = weak_from_this();
  const uint64_t hub_id = hub_.Subscribe(g.TileOf(region_.min), g.TileOf(region_.max),
                                         [this, weak] {
                                           // Changes arriving while a read is posted ride along
                                           // with it.
                                           if (grid_posted_.exchange(true)) return;
                                           boost::asio::post(pool_, [weak] {
                                             if (auto self = weak.lock()) self->SendGrid(nullptr);
                                           });
                                         },
                                         {});
  const uint64_t scans_id = scans_.Listen([this, weak](const std::string& robot_id) {
    boost::asio::post(pool_, [weak, robot_id] {
      if (auto self = weak.lock()) self->SendRobot(robot_id);
    });
  });
  std::lock_guard lock(mu_);
  hub_id_ = hub_id;
  scans_id_ = scans_id;
}

void LiveFeed::Stop() {
  uint64_t hub_id = 0, scans_id = 0;
  {
    std::lock_guard lock(mu_);
    if (stopped_) return;
    stopped_ = true;
    hub_id = hub_id_;
    scans_id = scans_id_;
    sinks_.clear();
  }
  if (hub_id != 0) hub_.Unsubscribe(hub_id);
  if (scans_id != 0) scans_.Unlisten(scans_id);
}

void LiveFeed::Add(const std::shared_ptr<SessionSink>& sink) {
  std::lock_guard lock(mu_);
  if (!stopped_) sinks_[sink.get()] = sink;
}

void LiveFeed::Remove(const SessionSink* sink) {
  std::lock_guard lock(mu_);
  sinks_.erase(sink);
}

std::vector<std::shared_ptr<SessionSink>> LiveFeed::Sinks() const {
  std::lock_guard lock(mu_);
  std::vector<std::shared_ptr<SessionSink>> out;
  for (const auto& [key, weak] : sinks_) {
    if (auto s = weak.lock()) out.push_back(std::move(s));
  }
  return out;
}

void LiveFeed::SendCurrent(const std::shared_ptr<SessionSink>& sink, uint32_t channel) {
  std::weak_ptr<LiveFeed> weak = weak_from_this();
  boost::asio::post(pool_, [weak, sink, channel] {
    auto self = weak.lock();
    if (self == nullptr) return;
    if (channel == kGridChannel) {
      self->SendGrid(sink);
      return;
    }
    std::lock_guard order(self->robot_order_);
    const std::vector<std::shared_ptr<const RobotScan>> robots = self->scans_.All();
    if (robots.empty()) return;
    if (channel == kTransformsChannel) {
      sink->Deliver(channel, StampNs(robots.back()->stamp),
                    std::make_shared<const std::string>(EncodeTransforms(robots)));
      return;
    }
    for (const auto& robot : robots) {
      sink->Deliver(channel, StampNs(robot->stamp),
                    std::make_shared<const std::string>(EncodeScan(*robot)));
    }
  });
}

void LiveFeed::SendGrid(const std::shared_ptr<SessionSink>& to) {
  std::lock_guard order(grid_order_);
  if (to == nullptr) {
    grid_posted_ = false;  // a change published from here on posts another read
    const uint64_t id = [this] {
      std::lock_guard lock(mu_);
      return hub_id_;
    }();
    TileKey k;
    while (id != 0 && hub_.Take(id, &k)) {
    }
  }
  const std::vector<std::shared_ptr<SessionSink>> sinks =
      to != nullptr ? std::vector<std::shared_ptr<SessionSink>>{to} : Sinks();
  if (sinks.empty()) return;
  Result<Raster> raster = map_.ReadRegion(region_, layers_, 1);
  if (!raster.ok()) {
    spdlog::warn("event=foxglove_grid_failed reason=\"{}\"", raster.status().message());
    for (const auto& s : sinks)
      s->Warn("/map: cannot read the region: " + raster.status().message());
    return;
  }
  const uint64_t now = NowNs();
  auto grid = std::make_shared<const std::string>(EncodeGrid(*raster, now));
  for (const auto& s : sinks) s->Deliver(kGridChannel, now, grid);
}

void LiveFeed::SendRobot(const std::string& robot_id) {
  std::lock_guard order(robot_order_);
  const std::vector<std::shared_ptr<SessionSink>> sinks = Sinks();
  if (sinks.empty()) return;
  const std::shared_ptr<const RobotScan> scan = scans_.Find(robot_id);
  if (scan == nullptr) return;
  const uint64_t time = StampNs(scan->stamp);
  auto transforms = std::make_shared<const std::string>(EncodeTransforms(scans_.All()));
  auto cloud = std::make_shared<const std::string>(EncodeScan(*scan));
  for (const auto& s : sinks) {
    s->Deliver(kTransformsChannel, time, transforms);
    s->Deliver(kScansChannel, time, cloud);
  }
}

}  // namespace bgkmap::foxglove
