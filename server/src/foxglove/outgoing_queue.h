// What a Foxglove session has yet to send, in order, within a bound.
//
// A newer grid replaces one of the same subscription still waiting (not the one being written),
// so a client slower than the map's changes gets the latest grid, not every grid; every other
// frame (transforms, clouds, statuses) is sent as queued. A client that lets the bytes waiting
// behind the one being written pass the bound is too slow: the session drops it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

namespace bgkmap::foxglove {

class OutgoingQueue {
 public:
  struct Frame {
    std::shared_ptr<const std::string> bytes;
    bool binary = false;
    // The subscription of a grid (nullopt: not a grid). A client picks its subscription ids,
    // 0 among them, so no id can mean "not a grid".
    std::optional<uint32_t> grid_subscription;
  };

  explicit OutgoingQueue(size_t max_waiting_bytes) : max_waiting_bytes_(max_waiting_bytes) {}

  // Queues `frame` (a grid may replace a waiting one instead). False, with nothing queued, if
  // the waiting bytes would pass the bound.
  bool Add(Frame frame);
  // The frame to write next, now being written; null if none waits or one is being written.
  const Frame* StartWrite();
  // The frame being written went out.
  void FinishWrite();

  bool writing() const { return writing_; }
  size_t queued_bytes() const { return queued_bytes_; }

 private:
  const size_t max_waiting_bytes_;
  std::deque<Frame> frames_;
  size_t queued_bytes_ = 0;
  bool writing_ = false;  // frames_.front() is being written
};

}  // namespace bgkmap::foxglove
