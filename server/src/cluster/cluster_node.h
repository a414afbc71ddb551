// A bgkmapd running as a shard of a cluster (docs/scale-out.md): it appends the scans it
// receives to the cluster's log, builds the partitions it owns from the log (one reader for all
// of them) and serves their tiles, and answers queries
// by gathering tiles from their owners. The gRPC service in front is the single server's
// (rpc/): it calls Append() instead of the served map's SubmitScan(), and reads through
// reads() instead of the served map.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/server/server_config.h"
#include "cluster/cluster_log.h"
#include "cluster/cluster_reads.h"
#include "cluster/log_change_feed.h"
#include "cluster/membership.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"
#include "cluster/partition_replica.h"

namespace bgkmap::cluster {

// Checks and prepares a scan exactly as the node that accepted it did (the same parameters).
using ScanPreparer = std::function<Status(const v1::Scan&, PreparedScan*)>;

struct ClusterStatus {
  std::string node;
  std::vector<std::string> live_nodes;
  uint64_t partitions_known = 0;
  std::vector<ReplicaStats> replicas;  // the partitions this node serves or is catching up
};

class ClusterNode {
 public:
  // Connects, creates or checks the log and the buckets, and starts taking partitions.
  static Result<std::unique_ptr<ClusterNode>> Start(const ClusterConfig& config,
                                                    const MapParams& params,
                                                    const std::string& params_yaml,
                                                    ScanPreparer prepare);
  ~ClusterNode();  // leaves: stops the heartbeat (its partitions move when the lease expires)

  // Appends a checked and prepared scan to the log (durable on a majority of the log's replicas
  // when OK). Unavailable if the log cannot be reached.
  Result<Appended> Append(const v1::Scan& scan, const PreparedScan& prepared);
  // Appends a clear of `box` (map cells); its log sequence number once stored.
  Result<uint64_t> AppendClear(const CellBox& box);
  // Appends an import (a merge) of `tiles` at `keys`: the tiles are stored first, then one
  // log entry names them. Its log sequence number once stored.
  Result<uint64_t> AppendImport(std::span<const TileKey> keys,
                                std::span<const std::unique_ptr<Tile>> tiles);
  MapReads& reads() { return *reads_; }
  // Reports every later log entry's changed cells to `on_change` (Watch on this node); once.
  void FollowChanges(LogChangeFeed::OnChange on_change);
  ClusterStatus Describe() const;
  const PartitionLayout& layout() const { return layout_; }

 private:
  ClusterNode(const ClusterConfig& config, const MapParams& params, ScanPreparer prepare,
              std::unique_ptr<NatsClient> nats, std::unique_ptr<Membership> members);
  void Run();        // the membership loop
  void Rebalance();  // starts the partitions this node owns, stops those it no longer does
  // cluster.trim_lag_entries > 0: deletes the log's entries that every partition's newest
  // checkpoint holds (on the first live node, every 4 leases).
  void TrimLogIfDue();
  // A replica of `p` from its newest checkpoint (or empty), serving once it reads `end`.
  std::shared_ptr<PartitionReplica> TakePartition(PartitionKey p, uint64_t end);
  // The log reader: one ordered reader of the log for all of this node's partitions, started
  // again from an earlier entry when a new partition needs the log from its start.
  void ReadLog();
  std::vector<std::shared_ptr<PartitionReplica>> Replicas() const;
  // Decodes and prepares entry `msg` once for every replica that integrates it.
  void Dispatch(uint64_t sequence, natsMsg* msg,
                const std::vector<std::shared_ptr<PartitionReplica>>& to);
  // Copies the owned partitions of `to` that are due (cluster.checkpoint_scans) for the writer.
  void QueueCheckpoints(const std::vector<std::shared_ptr<PartitionReplica>>& to);
  void WriteCheckpoints();  // the checkpoint writer's loop

  const ClusterConfig config_;
  const MapParams params_;
  const ScanPreparer prepare_;
  const PartitionLayout layout_;
  std::unique_ptr<NatsClient> nats_;
  std::unique_ptr<Membership> members_;
  std::unique_ptr<ClusterReads> reads_;

  mutable std::mutex mu_;
  std::map<PartitionKey, std::shared_ptr<PartitionReplica>> replicas_;
  // Partitions served although another node owns them now, and since when (kept for a grace
  // period so the new owner can catch up before this one stops answering).
  std::map<PartitionKey, std::chrono::steady_clock::time_point> leaving_;
  std::vector<std::string> live_;
  uint64_t partitions_known_ = 0;

  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stop_ = false;
  std::thread loop_;
  std::thread reader_;

  std::mutex checkpoint_mu_;
  std::condition_variable checkpoint_cv_;
  std::map<PartitionKey, PartitionCheckpoint> pending_checkpoints_;  // newest per partition
  std::thread checkpoint_writer_;
  std::atomic<uint64_t> imports_{0};  // names this node's imports' chunks
  std::unique_ptr<LogChangeFeed> feed_;
  std::chrono::steady_clock::time_point
      next_trim_{};  // the membership loop's thread only  // stopped first when the node leaves
};

}  // namespace bgkmap::cluster
