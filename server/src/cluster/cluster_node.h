// A bgkmapd running as a shard of a cluster (docs/scale-out.md): it appends the scans it
// receives to the cluster's log, builds the partitions it owns from the log (one reader for all
// of them) and serves their tiles, and answers queries by gathering tiles from their owners.
// It is the cluster's implementation of the map port (serving/map_port.h), so the gRPC service
// and the web map in front are the single server's; the port's methods are in
// cluster_map_port.cc.
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

#include "bgkmap/core/georeference.h"
#include "bgkmap/server/server_config.h"
#include "cluster/cluster_log.h"
#include "cluster/cluster_reads.h"
#include "cluster/cluster_trust.h"
#include "cluster/log_change_feed.h"
#include "cluster/log_corrections.h"
#include "cluster/membership.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"
#include "cluster/partition_replica.h"
#include "cluster/region_streams.h"
#include "cluster/robot_ledger.h"
#include "serving/map_port.h"

namespace bgkmap::cluster {

// Checks and prepares a scan exactly as the node that accepted it did (the same parameters);
// with `pose` (not null) instead of the scan's own pose (a correction's).
using ScanPreparer = std::function<Status(const v1::Scan&, const Pose* pose, PreparedScan*)>;
// Runs a task on a worker (the server's query pool): what must not run on the caller's thread.
using Executor = std::function<void(std::function<void()>)>;

struct ClusterStatus {
  std::string node;
  std::vector<std::string> live_nodes;
  uint64_t partitions_known = 0;
  std::vector<ReplicaStats> replicas;  // the partitions this node serves or is catching up
};

class ClusterNode final : public MapPort {
 public:
  // Connects, creates or checks the log and the buckets, and starts taking partitions.
  // `georeference`: the configured one (a shard keeps it in memory); `executor`: where reads
  // that ask the log run instead of the caller's thread; `rule`: server.max_robots and
  // server.max_sequence_jump (every shard must run the same).
  static Result<std::unique_ptr<ClusterNode>> Start(const ClusterConfig& config,
                                                    const MapParams& params,
                                                    const std::string& params_yaml,
                                                    ScanPreparer prepare, Georeference georeference,
                                                    Executor executor, RobotSequenceRule rule);
  // Leaves: stops the heartbeat (its partitions move when the lease expires). Safe by
  // construction: whatever can touch a member stops before the member dies, in this order:
  //   1. the executor's tasks this node posted (Export, ReadVersion): waited for until each has
  //      run or been dropped by the executor;
  //   2. the change feed (its callback reaches the caller's OnChange): stopped and joined;
  //   3. the membership loop (its partition starts joined inside it), the log reader and the
  //      checkpoint writer: told to stop and joined;
  //   4. the replicas: all begin to stop at once (fetches waiting for the log are refused), then
  //      each is freed once nats.c will not run its fetch handler again (AsyncSubscription);
  //   5. the members, in reverse order of declaration (each uses only those declared before it):
  //      the ledger (its reader joined), the reads (their replies' handler waited for), the
  //      membership (its watchers joined), the NATS connection, the cluster key.
  // The caller's part: no MapPort call, and no call of an object a MapPort call returned (an
  // upload, an archive's chunks are the caller's and keep what they need), begins or is still
  // running once the destructor starts. MapServer stops gRPC, the HTTP and Foxglove ports and
  // joins its pools first.
  ~ClusterNode();

  // Reports every later log entry's changed cells to `on_change` (Watch on this node); once.
  void FollowChanges(LogChangeFeed::OnChange on_change);
  ClusterStatus Describe() const;
  const PartitionLayout& layout() const { return layout_; }

  // ---- MapPort. Changes go to the log: a scan, a clear, an import or a retirement is answered
  // (on the caller's thread) once the log has stored it, its map version the entry's log
  // sequence. Robots' sequence numbers (and server.max_robots, server.max_sequence_jump) are
  // judged in the log's order by the partitions and by this node's RobotLedger; a scan's or a
  // retirement's answer is the ledger's verdict on its entry. A retry the log stores once is
  // answered as a duplicate (or refused again, if its entry was). An export is a snapshot point
  // in the log (Export). A pose correction or a scan removal is one entry too, after which each
  // partition it touches is rebuilt from the log (cluster_corrections.cc); it needs the whole
  // log (cluster.trim_lag_entries: 0).
  const MapParams& params() const override { return params_; }
  const GridGeometry& geometry() const override { return layout_.geometry(); }
  Status Offers(Operation operation) const override;
  // The log is the retained scans, unless it is trimmed.
  bool retains_scans() const override { return config_.trim_lag_entries == 0; }
  uint64_t retained_records_bound() const override {
    return retains_scans() ? ledger_->last_sequence() : 0;
  }
  bool TakeDuplicate(const std::string&, uint64_t, uint64_t*) override { return false; }
  void CountRejected(const std::string&) override {}
  RobotAdmission SubmitScan(ScanOrigin origin, std::shared_ptr<const PreparedScan> scan,
                            std::function<void(ScanOutcome)> done,
                            uint64_t* last_sequence = nullptr) override;
  void SubmitClear(const CellBox& box, std::function<void(ClearOutcome)> done) override;
  // Spooled to the system's temporary directory and checked like a single server's (sums that
  // would not be finite: CheckImportSums); the tiles are then stored beside the log and one
  // entry names them (AppendImport).
  Result<std::unique_ptr<ArchiveUpload>> BeginImport() override;
  void SubmitExport(const std::optional<CellBox>& box,
                    std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) override;
  void SubmitCorrection(CorrectionSpec spec, std::function<void(CorrectionOutcome)> done) override;
  void RetireRobot(const std::string& robot_id,
                   std::function<void(Result<RobotStats>)> done) override;
  // Bytes and messages this node's NATS connection has received since start (what the log,
  // the region streams, the tile fetches and the membership cost this shard).
  std::pair<uint64_t, uint64_t> NatsReceived() const;
  // Reads gather tiles from the partitions' owners (ClusterReads).
  uint64_t applied_version() const override { return reads_->applied_version(); }
  Result<Raster> ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                            int stride) override {
    return reads_->ReadRegion(box, layers, stride);
  }
  Result<std::vector<CellEstimate>> ReadCells(std::span<const CellIndex> cells) override {
    return reads_->ReadCells(cells);
  }
  Result<TileContent> ReadTile(TileKey key, const std::vector<Layer>& layers) override {
    return reads_->ReadTile(key, layers);
  }
  Result<std::vector<TileKey>> ListKnownTiles(TileKey min, TileKey max) override {
    return reads_->ListKnownTiles(min, max);
  }
  uint64_t history_id() const override { return reads_->history_id(); }
  Result<std::vector<ChangedTile>> TilesChangedSince(TileKey min, TileKey max,
                                                     uint64_t since) override {
    return reads_->TilesChangedSince(min, max, since);
  }
  // Info: the shard's place in the cluster, and the cluster's counts as of the last
  // ReadVersion (which gathers them from the partitions' owners; State() never waits on them).
  uint64_t known_version() const override { return reads_->known_version(); }
  // The cluster's robots as the ledger has read the log (counters since the log's start or the
  // checkpoint the ledger started from; no stamps, points or poses: the headers carry none).
  std::vector<RobotStats> Robots() const override { return ledger_->Robots(); }
  MapState State(bool with_disk_usage = false) override;
  // On a worker: the log's last sequence, and the cluster's counts as of at least it.
  void ReadVersion(std::function<void(uint64_t)> done) override;

 private:
  ClusterNode(const ClusterConfig& config, const MapParams& params, ScanPreparer prepare,
              std::unique_ptr<ClusterTrust> trust, std::unique_ptr<NatsClient> nats,
              std::unique_ptr<Membership> members, Georeference georeference, Executor executor,
              RobotSequenceRule rule);
  // Appends a checked and prepared scan to the log (durable on a majority of the log's replicas
  // when OK). OutOfRange when it is too large for the log; Unavailable if the log cannot be
  // reached.
  // `encoded`: origin.encoded(), taken once; `id_suffix`: AppendScan's.
  Result<Appended> Append(const ScanOrigin& origin, const std::string& encoded,
                          const PreparedScan& prepared, const std::string& id_suffix);
  // Appends the scan as SubmitScan does, and finds the ledger's verdict on its entry. A copy the
  // log stored already is a retry, answered by that entry's verdict, unless that entry was
  // refused by the robot-sequence rule (then the scan is appended again after it, to be judged
  // again as a single server judges a scan sent again) or its robot was retired since (then it
  // is a new scan of the robot's next epoch).
  Result<std::pair<Appended, std::optional<LedgerVerdict>>> AppendJudged(
      const ScanOrigin& origin, const PreparedScan& prepared);
  // Appends a clear of `box` (map cells); its log sequence number once stored.
  Result<uint64_t> AppendClear(const CellBox& box);
  // Appends an import (a merge) of `tiles` at `keys`: the tiles are stored first, then one
  // log entry names them. Its log sequence number once stored.
  Result<uint64_t> AppendImport(std::span<const TileKey> keys,
                                std::span<const std::unique_ptr<Tile>> tiles);
  // ExportMap: appends an export's snapshot point and gathers the tiles of the partitions that
  // meet `box` (all with data without one) exactly as of it from their owners.
  Result<std::unique_ptr<ArchiveChunks>> Export(const std::optional<CellBox>& box);
  // OutOfRange, as TileTable::CheckSumsFinite, if adding `tiles` to the cluster's tiles as of
  // the log's end would give a sum that is not finite (the tiles gathered from their owners).
  Status CheckImportSums(std::span<const TileKey> keys,
                         std::span<const std::unique_ptr<Tile>> tiles) const;
  Georeference georeference() const;
  // Ties the shard's map in a local frame to `georeference` (an import's).
  Status AdoptGeoreference(const Georeference& georeference);
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
  // The payload of scan entry `msg` for partition `p` (its region's copy first, if stored per
  // region), read again while the region streams are out of reach, until the node stops
  // (then Unavailable).
  Result<std::string> ScanPayload(uint64_t sequence, natsMsg* msg, PartitionKey p);
  // Decodes and prepares entry `msg` once for every replica that integrates it. `revisions`
  // (a rebuild's replay): scans prepared with their corrected poses or not integrated, and
  // correction and export entries passed.
  void Dispatch(uint64_t sequence, natsMsg* msg,
                const std::vector<std::shared_ptr<PartitionReplica>>& to,
                const Revisions* revisions = nullptr);
  // Dispatch of an entry that is not a scan (`header` read and verified).
  void DispatchChange(uint64_t sequence, natsMsg* msg, const LogEntryHeader& header,
                      const std::vector<std::shared_ptr<PartitionReplica>>& to,
                      const Revisions* revisions);
  // ---- Corrections (cluster_corrections.cc).
  // CorrectPoses / RemoveScans: resolves the robot's scans against the log as a single server
  // resolves them against its retained log (the same refusals), and appends one entry naming
  // them and the tiles a single server's re-integration affects (storage::AffectedTiles): the
  // entry is appended right after the last entry those tiles were grown over (JetStream's
  // expected last sequence), or they grow over the new entries and it is tried again.
  Result<CorrectionOutcome> Correct(const CorrectionSpec& spec);
  struct Resolved;
  // The named scans, their revisions, partitions and the affected tiles' seed, as of the log's
  // last entry now.
  Result<std::unique_ptr<Resolved>> Resolve(const CorrectionSpec& spec);
  // Whether entry `sequence` (its verified header) is a scan the robot rule admits, asked in
  // the log's order.
  using Admitted = std::function<bool(uint64_t sequence, const LogEntryHeader& header)>;
  // Correction entries among those GrowAffected read.
  struct Interleaved {
    // This call's own entry (the payload it appends), stored by a publish that nats.c retried
    // through an election and that was then refused for the sequence it expected.
    uint64_t own = 0;
    bool other = false;  // another correction
  };
  // Grows `resolved`'s affected tiles over the log's entries first..last; fills `*seen` (if not
  // null) with the correction entries among them, `own_payload` telling this call's own.
  Status GrowAffected(uint64_t first, uint64_t last, const Admitted& admitted, Resolved* resolved,
                      const std::string& own_payload, Interleaved* seen) const;
  static constexpr int kCorrectionAttempts = 4;
  // Entry `log_sequence`, a scan, prepared again (with `pose` instead of its own, if not null).
  Result<PreparedScan> PrepareLogged(uint64_t log_sequence, const Pose* pose) const;
  // Correction entry `sequence`: the replicas of `to` whose partition it touches are rebuilt
  // (RebuildAt); the others stamp the `affected` tiles they hold.
  void ApplyCorrection(uint64_t sequence, const LogEntryHeader& header,
                       const std::vector<TileKey>& affected,
                       const std::vector<std::shared_ptr<PartitionReplica>>& to);
  // Replays the log's entries before `sequence` into fresh copies of `replicas` with the
  // revisions in force at `sequence`, then switches each replica to its copy at `sequence`,
  // the `affected` tiles stamped with it.
  Status RebuildAt(uint64_t sequence,
                   const std::vector<std::shared_ptr<PartitionReplica>>& replicas,
                   const std::vector<TileKey>& affected);
  // Copies the owned partitions of `to` that are due (cluster.checkpoint_scans) for the writer.
  void QueueCheckpoints(const std::vector<std::shared_ptr<PartitionReplica>>& to);
  void WriteCheckpoints();  // the checkpoint writer's loop
  // Runs `task` on the executor, counted until it has run or the executor dropped it: the
  // destructor waits for the count to be 0 (step 1 above).
  void Post(std::function<void()> task);
  void WaitForPostedTasks();

  const ClusterConfig config_;
  const MapParams params_;
  const ScanPreparer prepare_;
  const Executor executor_;
  const RobotSequenceRule rule_;
  mutable std::mutex georeference_mu_;
  Georeference georeference_;  // guarded by georeference_mu_
  const PartitionLayout layout_;
  const std::unique_ptr<ClusterTrust> trust_;  // the cluster key; outlives what uses it below
  std::unique_ptr<NatsClient> nats_;
  std::unique_ptr<RegionStreams> regions_;  // cluster.region_partitions (may be disabled)
  std::unique_ptr<Membership> members_;
  std::unique_ptr<ClusterReads> reads_;
  std::unique_ptr<RobotLedger> ledger_;
  mutable std::mutex summary_mu_;
  MapSummary summary_;  // the cluster's counts as of the last ReadVersion; guarded by summary_mu_

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
  std::atomic<uint64_t> imports_{0};                   // names this node's imports' chunks
  std::chrono::steady_clock::time_point next_trim_{};  // the membership loop's thread only

  std::mutex tasks_mu_;
  std::condition_variable tasks_cv_;
  size_t tasks_ = 0;  // posted to the executor, not yet run or dropped; guarded by tasks_mu_
  // Corrections this shard is resolving now, and the time of the last one it answered (Info).
  std::atomic<uint64_t> corrections_in_progress_{0};
  std::atomic<double> last_correction_seconds_{0};
  std::unique_ptr<LogChangeFeed> feed_;  // uses nats_, trust_ and layout_
};

}  // namespace bgkmap::cluster
