// The served map's background upkeep: the packing of tiles beyond storage.dense_tiles_mb and,
// when it persists, periodic checkpoints, eviction under
// storage.max_memory_mb, and the verification of every stored tile after start. Threads of its
// own, so no RPC and no scan waits for them except at the barriers they take.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>

#include "bgkmap/server/server_config.h"
#include "durability/durability.h"
#include "serving/served_map.h"

namespace bgkmap {

// storage.max_memory_mb bounds the map's memory: the tiles in memory, plus the copies of the
// changed ones that a checkpoint holds while it writes them (a copy, and its encoding in the
// write). Tiles get two thirds of the bound; changed tiles are kept to a quarter of that by
// checkpointing, so a checkpoint holds at most the remaining third.
uint64_t TileMemoryLimit(const StorageConfig& storage);

class MapMaintenance {
 public:
  MapMaintenance(ServedMap& map, const Durability& durability, const StorageConfig& config);
  ~MapMaintenance();  // Stop()

  // Starts the threads the configuration asks for (none for a map in memory).
  void Start();
  // Joins them; a last checkpoint is the caller's.
  void Stop();
  // Wakes the eviction thread (the tiles in memory, or the changed ones, are over their limit).
  void RequestEviction();
  // Calls `on_change(writable)` now and, from the checkpoint thread, within a second of each
  // change: false while writes are paused for lack of free space (null: stop calling).
  void WatchWritable(std::function<void(bool writable)> on_change);

 private:
  void CheckpointLoop();
  void EvictionLoop();

  ServedMap& map_;
  const Durability& durability_;
  const StorageConfig config_;

  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool eviction_requested_ = false;
  std::function<void(bool)> on_writable_;  // guarded by mu_
  bool reported_writable_ = true;
  std::atomic<bool> stop_verifying_{false};
  std::thread checkpointer_;
  std::thread evictor_;
  std::thread verifier_;
};

}  // namespace bgkmap
