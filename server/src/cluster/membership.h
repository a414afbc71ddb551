// Who serves which partition, decided through JetStream's key-value store, not by an election
// of our own:
//   - bucket bgkmap_nodes (TTL = cluster.lease_s): each node puts its name every lease_s / 4; a
//     node whose put has not been seen for lease_s (crash, cut off from NATS) is not live;
//   - bucket bgkmap_partitions: every partition that ever received a scan (created by the node
//     that appended it, before the append);
//   - bucket bgkmap_cluster: the map parameters every node must share.
// Both buckets are followed by one watcher each (a JetStream ordered consumer kept for the
// node's life), so asking who is live or which partitions exist costs no request.
// A partition's owner is the live node with the highest rendezvous hash of (node, partition):
// every node computes the same owner from the same keys, and a node's death moves only its
// partitions. Two nodes may briefly both serve a partition while the keys propagate; that is
// harmless, because a partition is a deterministic function of the log.
//
// With a cluster key every record is signed (cluster_trust.h): a heartbeat's value is the time
// it was made and an HMAC over the node's name and that time, and it counts only if the NATS
// server stored it within a lease (plus the clock skew) of that time, so a copied heartbeat
// keeps a dead node alive for kMaxClockSkew at most; a partition's value is an HMAC over its
// name; the parameters carry an HMAC over them. Records that fail are refused and counted;
// deletions in the nodes' bucket are ignored (a node's key only expires).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/core/status.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"

namespace bgkmap::cluster {

struct MembershipOptions {
  std::string node;
  int replicas = 1;
  double lease_s = 3;
};

class Membership {
 public:
  // Opens (or creates) the buckets and checks that `params_yaml` equals the cluster's
  // (FailedPrecondition naming the first line that differs). Parameters recorded without a
  // valid HMAC (not by a shard) are replaced by this node's. `trust` outlives the Membership.
  static Result<std::unique_ptr<Membership>> Open(const NatsClient& nats,
                                                  const MembershipOptions& options,
                                                  const std::string& params_yaml,
                                                  const ClusterTrust& trust);

  // This node is alive: call every lease_s / 4.
  Status Heartbeat();
  ~Membership();
  // The nodes whose heartbeat was seen within lease_s, sorted.
  std::vector<std::string> LiveNodes() const;
  // Every partition that has data, sorted.
  std::vector<PartitionKey> Partitions() const;
  // Records that `p` has data (idempotent, cached; a record without a valid HMAC is replaced).
  Status AddPartition(PartitionKey p);
  // Whether `p` has data, asked of the bucket (not the cache).
  Result<bool> HasPartition(PartitionKey p) const;
  // Every partition recorded in the bucket, read from it now (not this node's watched view,
  // which may lag another node's record).
  Result<std::vector<PartitionKey>> ListRecordedPartitions() const;

  // The owner of `p` among `live` ("" if none). With `region_partitions` > 0 the owner of its
  // region (region_streams.h): one shard owns all of a region's partitions.
  static std::string OwnerOf(PartitionKey p, const std::vector<std::string>& live,
                             int region_partitions = 0);

 private:
  Membership(const MembershipOptions& options, const ClusterTrust& trust, natsConnection* nc,
             kvStore* nodes, kvStore* partitions)
      : options_(options), trust_(trust), nc_(nc), nodes_(nodes), partitions_(partitions) {}
  Status StartWatching();
  void Watch(kvStore* bucket, bool nodes);
  // Whether `entry` of the nodes' bucket is a heartbeat a shard made, within a lease.
  bool TrustedHeartbeat(kvEntry* entry) const;
  // The value of partition `name`'s record (an HMAC over the name; "1" without a key).
  std::string PartitionValue(const std::string& name) const;
  bool TrustedPartition(kvEntry* entry) const;

  const MembershipOptions options_;
  const ClusterTrust& trust_;
  natsConnection* const nc_;  // the watchers' (for QuiesceSubscription)
  NatsPtr<kvStore> nodes_;
  NatsPtr<kvStore> partitions_;
  mutable std::mutex mu_;
  std::map<std::string, std::chrono::steady_clock::time_point> seen_;  // node -> last put
  std::set<PartitionKey> known_;                                       // partitions with data
  std::atomic<bool> stop_{false};
  std::vector<std::thread> watchers_;
};

}  // namespace bgkmap::cluster
