// One partition of the map on a shard: its tiles (with the halo its cells need), built by reading
// the cluster's log from the start in the log's order, and served to any node that asks
// (subject bgkmap.tiles.<partition>, queue group "owners") once it has caught up.
//
// Every entry of the log passes through, so the robots' sequence numbers are judged as a single
// server judges them (a scan at or below its robot's last sequence is not applied); only the
// scans whose halo holds this partition are decoded, prepared, cut to the halo (RestrictScan)
// and integrated. Tiles are stamped with the entry's log sequence number.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/v1/ingest.pb.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"

namespace bgkmap::cluster {

// Checks and prepares a scan exactly as the node that accepted it did (the same parameters).
using ScanPreparer = std::function<Status(const v1::Scan&, PreparedScan*)>;

struct ReplicaStats {
  PartitionKey key;
  uint64_t log_sequence = 0;  // entries read
  uint64_t scans_integrated = 0;
  uint64_t tiles = 0;
  bool serving = false;
  double catch_up_seconds = 0;  // from start to serving
};

class PartitionReplica {
 public:
  static Result<std::unique_ptr<PartitionReplica>> Start(const NatsClient& nats,
                                                         const PartitionLayout& layout,
                                                         PartitionKey key, const MapParams& params,
                                                         ScanPreparer prepare);
  ~PartitionReplica();  // stops reading and serving
  PartitionReplica(const PartitionReplica&) = delete;
  PartitionReplica& operator=(const PartitionReplica&) = delete;

  PartitionKey key() const { return key_; }
  ReplicaStats Stats() const;
  // Blocks until every entry up to `sequence` is applied, or `timeout_ms` passed (false).
  bool WaitFor(uint64_t sequence, int64_t timeout_ms) const;
  // Copies of the partition's own tiles (not the halo's), for tests and reports.
  std::unique_ptr<TerrainMap> Snapshot() const;

 private:
  PartitionReplica(const NatsClient& nats, const PartitionLayout& layout, PartitionKey key,
                   std::unique_ptr<TerrainMap> map, ScanPreparer prepare);
  void Run(natsSubscription* log, uint64_t serve_from);
  void Apply(natsMsg* msg);
  Status StartServing();
  static void OnFetch(natsConnection* nc, natsSubscription* sub, natsMsg* msg, void* self);
  void ServeFetch(natsMsg* msg);

  const NatsClient& nats_;
  const PartitionLayout& layout_;
  const PartitionKey key_;
  const CellBox halo_;
  const ScanPreparer prepare_;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();

  mutable std::shared_mutex map_mu_;  // the consumer writes, fetches read
  std::unique_ptr<TerrainMap> map_;

  mutable std::mutex progress_mu_;
  mutable std::condition_variable progress_cv_;
  uint64_t applied_ = 0;
  uint64_t scans_integrated_ = 0;
  double catch_up_seconds_ = 0;
  std::map<std::string, uint64_t> robot_last_;  // consumer thread only

  std::atomic<bool> stop_{false};
  std::atomic<bool> serving_{false};
  NatsPtr<natsSubscription> fetch_sub_;
  std::thread consumer_;
};

}  // namespace bgkmap::cluster
