// What changed in the cluster's map, as the log says, for Watch on any node: a headers-only
// reader of the log (no scan payloads cross the network) that reports, entry by entry in the
// log's order, the box of cells each entry can change. A node's Watch subscribers learn of every
// change anywhere in the cluster this way and read the changed tiles from their owners. An
// entry whose signed headers do not verify (VerifyEntry) is not reported.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <thread>

#include "bgkmap/core/grid.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"

namespace bgkmap::cluster {

class LogChangeFeed {
 public:
  // Called on the feed's thread with the log sequence of an entry and the cells it can change.
  using OnChange = std::function<void(uint64_t sequence, const CellBox& cells)>;

  // Starts reading at the entry after the log's current end; `nats`, `trust` and `layout`
  // outlive it.
  LogChangeFeed(const NatsClient& nats, const ClusterTrust& trust, const PartitionLayout& layout,
                OnChange on_change);
  ~LogChangeFeed();  // stops and joins the reader
  LogChangeFeed(const LogChangeFeed&) = delete;
  LogChangeFeed& operator=(const LogChangeFeed&) = delete;

  // The last entry reported (0: none yet).
  uint64_t last_sequence() const { return last_; }

 private:
  void Run();

  const NatsClient& nats_;
  const ClusterTrust& trust_;
  const PartitionLayout& layout_;
  const OnChange on_change_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> last_{0};
  std::thread reader_;
};

}  // namespace bgkmap::cluster
