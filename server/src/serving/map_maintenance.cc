#include "serving/map_maintenance.h"

#include <malloc.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <limits>

#include "serving/heap_trim_pacer.h"

namespace bgkmap {
namespace {

// Tiles only packed are handed back to the system at most this often (heap_trim_pacer.h).
constexpr auto kPackedTrimGap = std::chrono::seconds(10);

}  // namespace

uint64_t TileMemoryLimit(const StorageConfig& storage) {
  return (storage.max_memory_mb << 20) / 3 * 2;
}

MapMaintenance::MapMaintenance(ServedMap& map, const Durability& durability,
                               const StorageConfig& config)
    : map_(map), durability_(durability), config_(config) {}

MapMaintenance::~MapMaintenance() { Stop(); }

void MapMaintenance::Start() {
  // Packing tiles beyond the dense budget needs the eviction thread, a map in memory too.
  if (!durability_.persists()) {
    if (config_.dense_tiles_mb > 0) evictor_ = std::thread([this] { EvictionLoop(); });
    return;
  }
  checkpointer_ = std::thread([this] { CheckpointLoop(); });
  if (config_.max_memory_mb > 0) {
    map_.checkpointer().SetDirtyLimit(
        std::max<uint64_t>(1, TileMemoryLimit(config_) / 4 / map_.TileBytes()),
        [this] { RequestEviction(); });
  }
  if (config_.max_memory_mb > 0 || config_.dense_tiles_mb > 0) {
    evictor_ = std::thread([this] { EvictionLoop(); });
  }
  if (config_.verify_on_start) {
    verifier_ = std::thread([this] {
      const Durability::VerifyReport r = durability_.VerifyStoredTiles(stop_verifying_);
      spdlog::info(
          "event=verify_done tiles={} corrupt_tiles={} unreadable_tiles={} stopped={} "
          "seconds={:.3f}",
          r.tiles, r.corrupt, r.unreadable, r.stopped, r.seconds);
    });
  }
}

void MapMaintenance::Stop() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  stop_verifying_.store(true);
  for (std::thread* t : {&checkpointer_, &evictor_, &verifier_}) {
    if (t->joinable()) t->join();
  }
}

void MapMaintenance::WatchWritable(std::function<void(bool writable)> on_change) {
  std::lock_guard lock(mu_);
  on_writable_ = std::move(on_change);
  reported_writable_ = !durability_.writes_paused_for_space();
  if (on_writable_) on_writable_(reported_writable_);
}

void MapMaintenance::RequestEviction() {
  {
    std::lock_guard lock(mu_);
    if (eviction_requested_) return;
    eviction_requested_ = true;
  }
  cv_.notify_all();
}

void MapMaintenance::CheckpointLoop() {
  const auto interval = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::duration<double>(config_.checkpoint_interval_s));
  // After a write failure, checkpoint (which first resumes the store) every second rather than
  // every interval, so ingestion comes back soon after the disk has room.
  const auto retry =
      std::clamp(interval, std::chrono::milliseconds(1), std::chrono::milliseconds(1000));
  // A checkpoint due by size is taken within a tenth of a second: four robots log 13 MB/s, and
  // each second of delay adds that to the disk's peak (docs/storage.md, "Sizing").
  const auto tick = std::min(retry, std::chrono::milliseconds(100));
  auto last = std::chrono::steady_clock::now();
  std::unique_lock lock(mu_);
  while (!cv_.wait_for(lock, tick, [this] { return stopping_; })) {
    if (const bool writable = !durability_.writes_paused_for_space();
        on_writable_ && writable != reported_writable_) {
      reported_writable_ = writable;
      on_writable_(writable);
    }
    const auto since = std::chrono::steady_clock::now() - last;
    const bool due = durability_.write_failed()
                         ? since >= retry
                         : durability_.checkpoint_due_by_size() || since >= interval;
    if (!due) continue;
    lock.unlock();
    (void)map_.Checkpoint();  // a failure is logged; the log keeps the changes
    lock.lock();
    last = std::chrono::steady_clock::now();
  }
}

void MapMaintenance::EvictionLoop() {
  // No bound (only a dense budget, or a map in memory): Evict() packs, and drops nothing.
  const uint64_t limit = durability_.persists() && config_.max_memory_mb > 0
                             ? TileMemoryLimit(config_)
                             : std::numeric_limits<uint64_t>::max();
  // Evict to below the bound, so that eviction runs in batches rather than after every scan.
  const uint64_t target = limit / 10 * 8;
  // A checkpoint makes changed tiles evictable, but it writes every changed tile: when the
  // bound is smaller than what is being changed, take one at most this often.
  constexpr auto kMinCheckpointGap = std::chrono::milliseconds(20);
  auto last_checkpoint = std::chrono::steady_clock::now() - kMinCheckpointGap;
  HeapTrimPacer trim_pacer(kPackedTrimGap);
  std::unique_lock lock(mu_);
  while (!stopping_) {
    cv_.wait_for(lock, std::chrono::seconds(1),
                 [this] { return stopping_ || eviction_requested_; });
    if (stopping_) break;
    eviction_requested_ = false;
    lock.unlock();
    const ResidencyStats before = map_.Residency();
    uint64_t held = map_.Evict(target);
    if ((held > limit || map_.checkpointer().dirty_over_limit()) &&
        std::chrono::steady_clock::now() - last_checkpoint >= kMinCheckpointGap) {
      const Status s = map_.Checkpoint();
      last_checkpoint = std::chrono::steady_clock::now();
      if (s.ok()) held = map_.Evict(target);
    }
    // Hand the freed tiles back to the system: the heap keeps large free blocks otherwise
    // (KeepLargeAllocationsInHeap). Paced: heap_trim_pacer.h.
    const ResidencyStats after = map_.Residency();
    const bool evicted = after.tiles_evicted != before.tiles_evicted;
    const bool packed = after.tiles_packed != before.tiles_packed;
    if (trim_pacer.TrimNow(std::chrono::steady_clock::now(), packed, evicted)) malloc_trim(0);
    lock.lock();
    // Over the dense budget with only tiles in use (or used within the last second) dense: a
    // pass walks every tile under the residency's lock, which each pin waits for; requests
    // that come every scan are served at most every kIdlePassGap, not after every scan.
    if (!packed && !evicted) {
      constexpr auto kIdlePassGap = std::chrono::milliseconds(250);
      cv_.wait_for(lock, kIdlePassGap, [this] { return stopping_; });
    }
    if (held > limit && !eviction_requested_) {
      // Still over (tiles in use or the checkpoint gap): look again soon.
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      lock.lock();
      eviction_requested_ = true;
    }
  }
}

}  // namespace bgkmap
