#include "durability/checkpointer.h"

#include <spdlog/spdlog.h>

#include <chrono>

namespace bgkmap {

void Checkpointer::MarkChanged(std::span<const TileKey> tiles) {
  if (!persists_) return;  // nothing is ever written: keep no set
  bool over = false;
  {
    std::lock_guard lock(dirty_mu_);
    dirty_.insert(tiles.begin(), tiles.end());
    over = dirty_limit_ > 0 && dirty_.size() > dirty_limit_;
  }
  if (over) on_dirty_over_limit_();
}

void Checkpointer::SetDirtyLimit(size_t tiles, std::function<void()> on_over_limit) {
  std::lock_guard lock(dirty_mu_);
  dirty_limit_ = tiles;
  on_dirty_over_limit_ = std::move(on_over_limit);
}

size_t Checkpointer::dirty_tiles() const {
  std::lock_guard lock(dirty_mu_);
  return dirty_.size();
}

bool Checkpointer::dirty_over_limit() const {
  std::lock_guard lock(dirty_mu_);
  return dirty_limit_ > 0 && dirty_.size() > dirty_limit_;
}

CapturedCheckpoint Checkpointer::Capture(uint64_t version) {
  // Resume needs no other store call in flight: at a barrier, only checkpoints could be, and
  // they are ordered below.
  CapturedCheckpoint c;
  order_->acquire();
  c.order = std::shared_ptr<std::binary_semaphore>(
      order_.get(), [keep = order_](auto* slot) { slot->release(); });
  if (store_.write_failed()) {
    const bool paused = store_.writes_paused_for_space();
    const Status resumed = store_.Resume();
    if (resumed.ok()) {
      if (!paused) spdlog::info("event=storage_resumed");  // (a pause for space logs its own)
    } else if (store_.writes_paused_for_space()) {
      // A full disk is retried every second: logged once when it began (event=storage_full).
      spdlog::debug("event=storage_resume_failed reason=\"{}\"", resumed.message());
    } else {
      spdlog::warn("event=storage_resume_failed reason=\"{}\"", resumed.message());
    }
  }
  c.version = version;
  {
    std::lock_guard lock(dirty_mu_);
    c.keys.assign(dirty_.begin(), dirty_.end());
    dirty_.clear();
  }
  c.tiles = map_.CopyTiles(c.keys);
  return c;
}

Status Checkpointer::Write(CapturedCheckpoint captured) {
  if (!persists_) return Status::Ok();
  const auto t0 = std::chrono::steady_clock::now();
  Status s = store_.WriteCheckpoint(captured.version, captured.keys, captured.tiles);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!s.ok()) {
    spdlog::log(store_.writes_paused_for_space() ? spdlog::level::debug : spdlog::level::err,
                "event=checkpoint_failed version={} reason=\"{}\"", captured.version, s.message());
    std::lock_guard lock(dirty_mu_);
    dirty_.insert(captured.keys.begin(), captured.keys.end());
    return s;
  }
  if (!captured.keys.empty()) {
    spdlog::info("event=checkpoint version={} tiles={} seconds={:.3f}", captured.version,
                 captured.keys.size(), seconds);
  }
  return s;
}

}  // namespace bgkmap
