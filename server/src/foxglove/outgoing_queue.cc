#include "foxglove/outgoing_queue.h"

namespace bgkmap::foxglove {

bool OutgoingQueue::Add(Frame frame) {
  if (frame.grid_subscription) {
    for (size_t i = writing_ ? 1 : 0; i < frames_.size(); ++i) {
      if (frames_[i].grid_subscription != frame.grid_subscription) continue;
      queued_bytes_ = queued_bytes_ - frames_[i].bytes->size() + frame.bytes->size();
      frames_[i].bytes = std::move(frame.bytes);
      return true;
    }
  }
  const size_t waiting = queued_bytes_ - (writing_ ? frames_.front().bytes->size() : 0);
  if (waiting > 0 && waiting + frame.bytes->size() > max_waiting_bytes_) return false;
  queued_bytes_ += frame.bytes->size();
  frames_.push_back(std::move(frame));
  return true;
}

const OutgoingQueue::Frame* OutgoingQueue::StartWrite() {
  if (writing_ || frames_.empty()) return nullptr;
  writing_ = true;
  return &frames_.front();
}

void OutgoingQueue::FinishWrite() {
  if (!writing_) return;
  queued_bytes_ -= frames_.front().bytes->size();
  frames_.pop_front();
  writing_ = false;
}

}  // namespace bgkmap::foxglove
