// One partition of the map on a shard: its tiles (with the halo its cells need), built from the
// cluster's log in the log's order, and served to any node that asks (subject
// bgkmap.tiles.<partition>, queue group "owners") once it has caught up with the log's end as
// of its start.
//
// The node's log reader (LogReader) hands it every entry after the last it applied, so the robots'
// sequence numbers are judged by the single server's rule with its limits
// (serving/robot_sequence.h: a scan at or below its robot's last sequence, more than
// max_sequence_jump above it, or of a robot beyond max_robots is not applied; a retirement entry
// forgets the robot), exactly as the node's RobotLedger judges them;
// only the scans whose halo holds this partition are cut to the halo (RestrictScan) and
// integrated. Tiles are stamped with the entry's log sequence number. A fetch's reply carries
// an HMAC (header Bgkmap-Mac, TileReplyMac) over the request and the reply, so the asking node
// can tell it from a reply anyone else on NATS sends (cluster_trust.h).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/v1/cluster.pb.h"
#include "bgkmap/v1/ingest.pb.h"
#include "cluster/cluster_log.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/nats_subscription.h"
#include "cluster/partition_checkpoint.h"
#include "cluster/partition_layout.h"
#include "serving/robot_sequence.h"

namespace bgkmap::cluster {

struct ReplicaStats {
  PartitionKey key;
  uint64_t log_sequence = 0;  // entries applied
  uint64_t scans_integrated = 0;
  uint64_t tiles = 0;
  bool serving = false;
  double catch_up_seconds = 0;  // from creation to serving
  uint64_t restored_from = 0;   // the checkpoint's log sequence it started from (0: none)
};

// The HMAC of a tile fetch's reply: over the subject asked (the partition), the requester's
// reply subject (unique to one request), the request's bytes (its range, its min_log_sequence)
// and the reply's bytes, so a reply is good for the one request it answers.
std::string TileReplyMac(const ClusterTrust& trust, std::string_view subject,
                         std::string_view reply_to, std::string_view request,
                         std::string_view reply);
// Whether `mac` is TileReplyMac of the same (true without a key).
bool TileReplyVerifies(const ClusterTrust& trust, std::string_view mac, std::string_view subject,
                       std::string_view reply_to, std::string_view request, std::string_view reply);
inline constexpr const char* kTileReplyMacHeader = "Bgkmap-Mac";

class PartitionReplica {
 public:
  // `serve_from`: the log's last sequence at creation; it serves once it has applied that.
  // `restored` (optional): the checkpoint it starts from (its tiles are moved into `map`).
  // `trust` signs its fetch replies and outlives it.
  // `rule`: server.max_robots and server.max_sequence_jump, the same on every shard.
  PartitionReplica(const NatsClient& nats, const ClusterTrust& trust, const PartitionLayout& layout,
                   PartitionKey key, std::unique_ptr<TerrainMap> map, uint64_t serve_from,
                   RobotSequenceRule rule,
                   std::optional<PartitionCheckpoint> restored = std::nullopt);
  // BeginStop, then waits until the fetch handler has returned for the last time (nats.c's
  // word, AsyncSubscription): no fetch runs on a freed replica, however long the drain takes.
  ~PartitionReplica();
  PartitionReplica(const PartitionReplica&) = delete;
  PartitionReplica& operator=(const PartitionReplica&) = delete;

  PartitionKey key() const { return key_; }
  uint64_t applied() const;
  // Entry `sequence` (after applied()): records its robot's sequence and says whether its scan
  // is to be integrated here (not a duplicate, and it touches this partition; `revised`: a
  // corrected scan, whose partitions the header does not tell, is integrated if admitted, and
  // Apply cuts it to the halo).
  bool Admit(uint64_t sequence, const LogEntryHeader& header, bool revised = false);
  // Switches to `rebuilt`'s tiles (a replay of the log before entry `sequence` with a
  // correction's revisions, ClusterNode::RebuildAt) and applies entry `sequence`, stamping the
  // tiles of `affected` as ApplyStamp does. The robots' sequences stay: a correction changes no
  // admission.
  void AdoptRebuilt(PartitionReplica& rebuilt, uint64_t sequence,
                    const std::vector<TileKey>& affected);
  // Applies entry `sequence`, a correction: the tiles of `affected` (sorted) this replica holds
  // get `sequence` as their version, as a single server gives every tile its re-integration
  // affects the correction's version. (A single server also makes an empty tile of an affected
  // one the re-integration leaves without data; no replica does: an export skips empty tiles
  // and Info counts tiles with data, so neither shows it.)
  void ApplyStamp(uint64_t sequence, const std::vector<TileKey>& affected);
  // Applies entry `sequence`: integrates `prepared` (the whole scan; null: nothing here) cut to
  // the halo. Then serves, once caught up.
  void Apply(uint64_t sequence, const PreparedScan* prepared);
  // Applies entry `sequence`, the retirement of `robot_id`: its sequence state is forgotten.
  void ApplyRetire(uint64_t sequence, const std::string& robot_id);
  // Applies entry `sequence`, an export's snapshot point: keeps a copy of the partition's own
  // tiles as of it (the newest kKeptSnapshots), served to fetches with at_log_sequence.
  void ApplyExport(uint64_t sequence);
  static constexpr size_t kKeptSnapshots = 4;
  // Applies entry `sequence`, a clear of `box` (map cells): the cells of the box in this
  // partition and its halo are forgotten, as a single server forgets them.
  void ApplyClear(uint64_t sequence, const CellBox& box);
  // Applies entry `sequence`, an import: adds the statistics of every tile that meets this
  // partition's halo (a merge, as a single server's import: caps applied after the sum).
  void ApplyImport(uint64_t sequence,
                   const std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>& tiles);
  // Stops taking fetches without waiting: many replicas stop in parallel. Fetches already
  // received are answered at once, those still waiting for log entries with a refusal (the
  // asker tries the partition's next owner): the replica will not read the log again.
  void BeginStop();
  // On the log reader's thread, between entries: a copy of the partition's state when
  // `every_scans` scans were integrated since the last one, or (lag_entries > 0) when the last
  // one lags the entries applied by lag_entries (so the log can be trimmed); else nullopt.
  std::optional<PartitionCheckpoint> CheckpointIfDue(uint32_t every_scans,
                                                     uint32_t lag_entries = 0);

  ReplicaStats Stats() const;
  // Blocks until every entry up to `sequence` is applied (true), or `timeout_ms` passed or the
  // replica began to stop (false).
  bool WaitFor(uint64_t sequence, int64_t timeout_ms) const;
  // Copies of the partition's own tiles (not the halo's), for tests and reports.
  std::unique_ptr<TerrainMap> Snapshot() const;

 private:
  void StartServing();
  void ServeFetch(natsMsg* msg);
  // Fills `reply` from the snapshot at request.at_log_sequence(): tiles in [lo, hi] from
  // request.skip(), at most `budget` bytes.
  void ServeSnapshot(const v1::TileFetchRequest& request, TileKey lo, TileKey hi, int64_t budget,
                     v1::TileFetchReply* reply) const;
  // ApplyStamp's stamps (map_mu_ held, exclusive).
  void StampLocked(uint64_t sequence, const std::vector<TileKey>& affected);
  // StampLocked, then `sequence` applied (still under `map_lock`, which it then releases), and
  // serving started if the partition has caught up: the end of a correction's stamp or swap.
  void StampAndAdvance(std::unique_lock<std::shared_mutex>& map_lock, uint64_t sequence,
                       const std::vector<TileKey>& affected);
  // Counts the partition's tiles with lo <= key <= hi into `out` (map_mu_ held, shared).
  void SummarizeInto(TileKey lo, TileKey hi, v1::PartitionSummary* out) const;

  const NatsClient& nats_;
  const ClusterTrust& trust_;
  const PartitionLayout& layout_;
  const PartitionKey key_;
  const CellBox halo_;
  const uint64_t serve_from_;
  const std::chrono::steady_clock::time_point created_ = std::chrono::steady_clock::now();

  mutable std::shared_mutex map_mu_;  // the log reader writes, fetches read
  std::unique_ptr<TerrainMap> map_;
  // Export snapshots by log sequence: the partition's own tiles, sorted by key.
  mutable std::mutex snapshots_mu_;
  std::map<uint64_t, std::shared_ptr<const std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>>>
      snapshots_;

  mutable std::mutex progress_mu_;
  mutable std::condition_variable progress_cv_;
  bool stopping_ = false;  // BeginStop was called: WaitFor waits no longer
  uint64_t applied_ = 0;
  uint64_t scans_integrated_ = 0;
  double catch_up_seconds_ = 0;
  const RobotSequenceRule sequence_rule_;
  std::map<std::string, uint64_t> robot_last_;  // the log reader's thread only
  uint64_t restored_from_ = 0;
  uint64_t checkpointed_scans_ = 0;     // scans_integrated_ at the last checkpoint
  uint64_t checkpointed_sequence_ = 0;  // the log sequence of the last checkpoint (or restore)

  std::mutex serve_mu_;  // guards fetch_sub_ and stopped_
  bool stopped_ = false;
  std::atomic<bool> serving_{false};
  // Last: its handler uses every member above, and its destruction waits for the handler.
  std::unique_ptr<AsyncSubscription> fetch_sub_;
};

}  // namespace bgkmap::cluster
