#include "cluster/cluster_node.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <set>
#include <sstream>
#include <thread>

#include "bgkmap/v1/types.pb.h"
#include "cluster/quiet_scratch.h"

namespace bgkmap::cluster {
namespace {

std::vector<std::string> SplitServers(const std::string& list) {
  std::vector<std::string> out;
  std::istringstream in(list);
  for (std::string s; std::getline(in, s, ',');) {
    s.erase(0, s.find_first_not_of(" \t"));
    s.erase(s.find_last_not_of(" \t") + 1);
    if (!s.empty()) out.push_back(s);
  }
  return out;
}

// NATS may be starting with us: a clustered JetStream answers once it has elected its meta
// leader, and a new stream or bucket once it has a leader of its own. Each step of a shard's start
// is retried until one deadline, saying what it waits for; a refusal that waiting cannot change
// (FailedPrecondition: the cluster's settings differ from this shard's) fails at once.
class JetStreamWait {
 public:
  explicit JetStreamWait(double seconds)
      : deadline_(std::chrono::steady_clock::now() +
                  std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000))) {}

  template <typename Step>
  Status Until(const char* what, Step step) const {
    for (int attempt = 1;; ++attempt) {
      Status s = step();
      if (s.ok() || s.code() == Status::Code::kFailedPrecondition) return s;
      if (std::chrono::steady_clock::now() > deadline_) {
        return Status::Unavailable(std::string("cluster: NATS JetStream did not answer for ") +
                                   what + " within cluster.startup_wait_s: " + s.message());
      }
      spdlog::info("event=cluster_waiting_for_jetstream step=\"{}\" attempt={} reason=\"{}\"", what,
                   attempt, s.message());
      std::this_thread::sleep_for(std::chrono::milliseconds(std::min(250 * attempt, 2000)));
    }
  }

 private:
  std::chrono::steady_clock::time_point deadline_;
};

}  // namespace

ClusterNode::ClusterNode(const ClusterConfig& config, const MapParams& params, ScanPreparer prepare,
                         std::unique_ptr<ClusterTrust> trust, std::unique_ptr<NatsClient> nats,
                         std::unique_ptr<Membership> members, Georeference georeference,
                         Executor executor, RobotSequenceRule rule)
    : config_(config),
      params_(params),
      prepare_(std::move(prepare)),
      executor_(std::move(executor)),
      rule_(rule),
      georeference_(std::move(georeference)),
      layout_(params, static_cast<int>(config.partition_tiles)),
      trust_(std::move(trust)),
      nats_(std::move(nats)),
      regions_(std::make_unique<RegionStreams>(
          *nats_, RegionStreamOptions{static_cast<int>(config.region_partitions),
                                      static_cast<int>(config.replicas), config.dedupe_window_s})),
      members_(std::move(members)) {
  // A takeover waits for the lease to expire, then for the new owner to read the log.
  reads_ = std::make_unique<ClusterReads>(*nats_, *trust_, layout_, *members_, params_,
                                          static_cast<int64_t>(config.lease_s * 1000) + 10000);
  ledger_ = std::make_unique<RobotLedger>(*nats_, *trust_, *members_, rule_);
}

Result<std::unique_ptr<ClusterNode>> ClusterNode::Start(
    const ClusterConfig& config, const MapParams& params, const std::string& params_yaml,
    ScanPreparer prepare, Georeference georeference, Executor executor, RobotSequenceRule rule) {
  // The key first: a shard that cannot read it does not touch NATS. (Without one, the
  // configuration was checked to say cluster.insecure: true.)
  Result<std::unique_ptr<ClusterTrust>> trust = ClusterTrust::Open(config.key_file);
  if (!trust.ok()) return trust.status();
  if (!(*trust)->keyed()) {
    spdlog::warn(
        "event=cluster_insecure reason=\"cluster.insecure: true and no cluster.key_file: log "
        "entries, tile replies and membership records are not signed\"");
  }
  Result<std::unique_ptr<NatsClient>> nats =
      NatsClient::Connect(SplitServers(config.nats), "bgkmapd-" + config.node,
                          {config.nats_credentials, config.nats_tls.ca_file,
                           config.nats_tls.cert_file, config.nats_tls.key_file});
  if (!nats.ok()) return nats.status();
  LogStreamOptions log;
  log.replicas = static_cast<int>(config.replicas);
  log.dedupe_window_s = config.dedupe_window_s;
  const JetStreamWait wait(config.startup_wait_s);
  if (Status s = wait.Until("the log stream", [&] { return EnsureLogStream(**nats, log); });
      !s.ok()) {
    return s;
  }
  if (Status s = wait.Until(
          "the checkpoint stream",
          [&] { return EnsureCheckpointStream(**nats, static_cast<int>(config.replicas)); });
      !s.ok()) {
    return s;
  }
  MembershipOptions mo;
  mo.node = config.node;
  mo.replicas = static_cast<int>(config.replicas);
  mo.lease_s = config.lease_s;
  std::unique_ptr<Membership> opened;
  if (Status s = wait.Until("the membership buckets",
                            [&] {
                              Result<std::unique_ptr<Membership>> m =
                                  Membership::Open(**nats, mo, params_yaml, **trust);
                              if (m.ok()) opened = std::move(m).value();
                              return m.status();
                            });
      !s.ok()) {
    return s;
  }
  std::unique_ptr<ClusterNode> node(new ClusterNode(
      config, params, std::move(prepare), std::move(trust).value(), std::move(nats).value(),
      std::move(opened), std::move(georeference), std::move(executor), rule));
  if (Status s = wait.Until("the first heartbeat", [&] { return node->members_->Heartbeat(); });
      !s.ok()) {
    return s;
  }
  node->loop_ = std::thread([n = node.get()] { n->Run(); });
  node->checkpoint_writer_ = std::thread([n = node.get()] { n->WriteCheckpoints(); });
  node->reader_ = std::thread([n = node.get()] { n->ReadLog(); });
  spdlog::info("event=cluster_joined node={} partition_tiles={} halo_cells={}", config.node,
               config.partition_tiles, node->layout_.halo_cells());
  return node;
}

void ClusterNode::FollowChanges(LogChangeFeed::OnChange on_change) {
  if (!feed_) {
    feed_ = std::make_unique<LogChangeFeed>(*nats_, *trust_, layout_, std::move(on_change));
  }
}

ClusterNode::~ClusterNode() {
  // The order the header promises.
  WaitForPostedTasks();
  feed_.reset();
  {
    std::lock_guard lock(stop_mu_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (loop_.joinable()) loop_.join();
  if (reader_.joinable()) reader_.join();
  checkpoint_cv_.notify_all();
  if (checkpoint_writer_.joinable()) checkpoint_writer_.join();
  std::map<PartitionKey, std::shared_ptr<PartitionReplica>> replicas;
  {
    std::lock_guard lock(mu_);
    replicas.swap(replicas_);
  }
  for (auto& [p, r] : replicas) r->BeginStop();
  replicas.clear();  // each waits for its fetch handler's last return
}

void ClusterNode::Post(std::function<void()> task) {
  {
    std::lock_guard lock(tasks_mu_);
    ++tasks_;
  }
  // Counted down when the executor destroys the task, whether it ran it or dropped it unrun.
  struct Done {
    explicit Done(ClusterNode* n) : node(n) {}
    Done(const Done&) = delete;
    Done& operator=(const Done&) = delete;
    ClusterNode* node;
    ~Done() {
      std::lock_guard lock(node->tasks_mu_);
      --node->tasks_;
      node->tasks_cv_.notify_all();
    }
  };
  executor_([task = std::move(task), done = std::make_shared<Done>(this)] {
    task();
    static_cast<void>(done);
  });
}

void ClusterNode::WaitForPostedTasks() {
  std::unique_lock lock(tasks_mu_);
  tasks_cv_.wait(lock, [this] { return tasks_ == 0; });
}

Result<Appended> ClusterNode::Append(const ScanOrigin& origin, const std::string& encoded,
                                     const PreparedScan& prepared, const std::string& id_suffix) {
  // Refused before anything is recorded: the log takes messages up to the servers' max_payload.
  if (static_cast<int64_t>(encoded.size()) + 1024 > nats_->max_payload()) {
    return Status::OutOfRange("scan: " + std::to_string(encoded.size()) +
                              " bytes exceed the NATS servers' max_payload of " +
                              std::to_string(nats_->max_payload()) +
                              " bytes (nats-server: max_payload, up to 64 MB)");
  }
  const CellBox reach = layout_.Reach(prepared);
  const std::vector<PartitionKey> touched = layout_.Covering(reach);
  // Recorded before the append: an owner that learns of the partition reads the log from its
  // start, so it finds the scan whenever it learns.
  for (PartitionKey p : touched) {
    if (Status s = members_->AddPartition(p); !s.ok()) return Status::Unavailable(s.message());
  }
  return AppendScan(*nats_, *trust_, *regions_, encoded, origin.robot_id, origin.sequence,
                    id_suffix, touched, reach);
}

Result<uint64_t> ClusterNode::AppendClear(const CellBox& box) {
  // Every partition whose halo meets the box keeps copies of its cells.
  CellBox reach = box;
  const int h = layout_.halo_cells();
  reach.min = {reach.min.x - h, reach.min.y - h};
  reach.max = {reach.max.x + h, reach.max.y + h};
  return cluster::AppendClear(*nats_, *trust_, box, layout_.Covering(reach));
}

Result<uint64_t> ClusterNode::AppendImport(std::span<const TileKey> keys,
                                           std::span<const std::unique_ptr<Tile>> tiles) {
  std::vector<const Tile*> adding;
  std::set<PartitionKey> own, touched;
  CellBox changes;  // an import changes its own tiles' cells only
  const GridGeometry& g = layout_.geometry();
  const int h = layout_.halo_cells();
  for (size_t i = 0; i < keys.size(); ++i) {
    adding.push_back(tiles[i].get());
    const CellBox box = g.TileBox(keys[i]);
    changes.Extend(box.min);
    changes.Extend(box.max);
    own.insert(layout_.PartitionOf(keys[i]));
    const CellBox reach{{box.min.x - h, box.min.y - h}, {box.max.x + h, box.max.y + h}};
    for (PartitionKey p : layout_.Covering(reach)) touched.insert(p);
  }
  // The partitions that now have data get owners before the entry is read.
  for (PartitionKey p : own) {
    if (Status s = members_->AddPartition(p); !s.ok()) return Status::Unavailable(s.message());
  }
  const std::string id =
      config_.node + "-" +
      std::to_string(std::chrono::system_clock::now().time_since_epoch().count()) + "-" +
      std::to_string(imports_++);
  Result<std::string> manifest = StoreImportTiles(*nats_, id, keys, adding);
  if (!manifest.ok()) return Status::Unavailable(manifest.status().message());
  return cluster::AppendImport(*nats_, *trust_, id, *manifest, {touched.begin(), touched.end()},
                               changes);
}

void ClusterNode::TrimLogIfDue() {
  if (config_.trim_lag_entries == 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (now < next_trim_) return;
  next_trim_ = now + std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 4000));
  {
    // One node trims (any could: a trim is idempotent): the first live one.
    std::lock_guard lock(mu_);
    if (live_.empty() || live_.front() != config_.node) return;
  }
  // In this order: the log's end, then the partitions, then their checkpoints. A partition
  // recorded after the listing was recorded before its first entry, so after `end`: the
  // entries up to the floor below are in every partition's checkpoint, listed or not.
  Result<uint64_t> end = LastSequence(*nats_);
  if (!end.ok()) return;
  Result<std::vector<PartitionKey>> partitions = members_->ListRecordedPartitions();
  if (!partitions.ok()) {
    spdlog::warn("event=cluster_log_trim_skipped reason=\"{}\"", partitions.status().message());
    return;
  }
  uint64_t floor = *end;
  for (PartitionKey p : *partitions) {
    Result<std::optional<uint64_t>> c = ReadCheckpointSequence(*nats_, *trust_, p);
    if (!c.ok() || !c->has_value()) return;  // a partition without one holds the whole log
    floor = std::min(floor, **c);
  }
  Result<uint64_t> first = FirstSequence(*nats_);
  if (!first.ok() || floor + 1 <= *first) return;
  if (Status s = TrimLog(*nats_, floor + 1); !s.ok()) {
    spdlog::warn("event=cluster_log_trim_failed reason=\"{}\"", s.message());
    return;
  }
  spdlog::info("event=cluster_log_trimmed kept_from={} last={} partitions={}", floor + 1, *end,
               partitions->size());
}

void ClusterNode::Run() {
  const auto period = std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 250));
  // Partitions are taken only after one lease: by then this node has seen every live node's
  // heartbeat, so nodes started together split the partitions instead of each taking all.
  const auto first_rebalance =
      std::chrono::steady_clock::now() +
      std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 1000));
  std::unique_lock lock(stop_mu_);
  while (!stop_cv_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    if (Status s = members_->Heartbeat(); !s.ok()) {
      spdlog::warn("event=cluster_heartbeat_failed reason=\"{}\"", s.message());
    }
    if (std::chrono::steady_clock::now() >= first_rebalance) {
      Rebalance();
      TrimLogIfDue();
    }
    lock.lock();
  }
}

void ClusterNode::Rebalance() {
  std::vector<std::string> live = members_->LiveNodes();
  const std::vector<PartitionKey> known = members_->Partitions();
  // A node always counts itself: its own key may lag its first heartbeat.
  if (std::find(live.begin(), live.end(), config_.node) == live.end()) {
    live.push_back(config_.node);
    std::sort(live.begin(), live.end());
  }
  const auto now = std::chrono::steady_clock::now();
  const auto grace = std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 2000));
  std::vector<std::shared_ptr<PartitionReplica>> stopped;
  std::vector<PartitionKey> to_take;
  {
    std::lock_guard lock(mu_);
    live_ = live;
    partitions_known_ = known.size();
    for (PartitionKey p : known) {
      const bool mine =
          Membership::OwnerOf(p, live, static_cast<int>(config_.region_partitions)) == config_.node;
      const bool running = replicas_.count(p) != 0;
      if (mine) {
        leaving_.erase(p);
        if (!running) to_take.push_back(p);
      } else if (running) {
        auto [it, is_new] = leaving_.try_emplace(p, now);
        if (now - it->second < grace) continue;
        spdlog::info("event=partition_released partition={} node={}", PartitionName(p),
                     config_.node);
        replicas_[p]->BeginStop();
        stopped.push_back(std::move(replicas_[p]));
        replicas_.erase(p);
        leaving_.erase(it);
      }
    }
  }
  stopped.clear();  // outside the lock: a replica's stop waits for its threads
  if (to_take.empty()) return;
  // Without the lock (the log reader goes on): each new partition serves once it has read the
  // log up to its end as of now, starting from its newest checkpoint if there is one. The
  // checkpoints are read a few at a time.
  Result<uint64_t> end = LastSequence(*nats_);
  if (!end.ok()) {
    spdlog::warn("event=partition_start_failed reason=\"{}\"", end.status().message());
    return;
  }
  constexpr size_t kParallelReads = 8;
  for (size_t first = 0; first < to_take.size(); first += kParallelReads) {
    std::vector<std::future<std::shared_ptr<PartitionReplica>>> started;
    for (size_t i = first; i < std::min(to_take.size(), first + kParallelReads); ++i) {
      started.push_back(std::async(std::launch::async, [this, p = to_take[i], end = *end] {
        return TakePartition(p, end);
      }));
    }
    std::lock_guard lock(mu_);
    for (auto& f : started) {
      std::shared_ptr<PartitionReplica> r = f.get();
      if (r != nullptr) replicas_[r->key()] = std::move(r);
    }
  }
}

std::shared_ptr<PartitionReplica> ClusterNode::TakePartition(PartitionKey p, uint64_t end) {
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
  if (!map.ok()) return nullptr;
  Result<std::optional<PartitionCheckpoint>> restored = ReadCheckpoint(*nats_, *trust_, p, params_);
  if (restored.ok() && restored->has_value()) {
    // An older checkpoint than the log still holds the entries after (a manifest published
    // again): the entries between are gone, so it cannot be the partition's.
    Result<uint64_t> first = FirstSequence(*nats_);
    if (first.ok() && (*restored)->log_sequence + 1 < *first) {
      restored = Status::DataLoss(
          "its newest checkpoint (log entry " + std::to_string((*restored)->log_sequence) +
          ") is older than the log's first entry " + std::to_string(*first));
    }
  }
  if (!restored.ok()) {
    spdlog::warn("event=partition_checkpoint_unreadable partition={} reason=\"{}\"",
                 PartitionName(p), restored.status().message());
    // Rebuilt from the log's start instead, if the log still has it. A trimmed log does not:
    // the partition stays unserved (queries answer UNAVAILABLE naming it) rather than served
    // without its older scans, and is tried again at the next rebalance. (A partition that never
    // had a checkpoint has all its entries: it was recorded before its first entry, and the
    // log is only trimmed below checkpoints of every partition recorded.)
    Result<uint64_t> first = FirstSequence(*nats_);
    if (!first.ok() || *first > 1) {
      spdlog::error("event=partition_not_taken partition={} reason=\"{}\"", PartitionName(p),
                    first.ok() ? "its checkpoint cannot be read and the log was trimmed to entry " +
                                     std::to_string(*first)
                               : first.status().message());
      return nullptr;
    }
    restored = std::optional<PartitionCheckpoint>();
  }
  const uint64_t from = *restored ? (*restored)->log_sequence : 0;
  const size_t tiles = *restored ? (*restored)->tiles.size() : 0;
  spdlog::info("event=partition_taken partition={} node={} restored_from={} tiles={}",
               PartitionName(p), config_.node, from, tiles);
  return std::make_shared<PartitionReplica>(*nats_, *trust_, layout_, p, std::move(map).value(),
                                            end, rule_, std::move(restored).value());
}

std::vector<std::shared_ptr<PartitionReplica>> ClusterNode::Replicas() const {
  std::lock_guard lock(mu_);
  std::vector<std::shared_ptr<PartitionReplica>> out;
  for (const auto& [p, r] : replicas_) out.push_back(r);
  return out;
}

void ClusterNode::ReadLog() {
  LiveSubscription sub;
  uint64_t passed = 0;  // the last entry the current reader delivered (its start - 1 at first)
  // This thread prepares and integrates every scan: its scratch goes back after a quiet spell
  // as long as a single server's workers wait (ServedMapOptions::scratch_idle).
  QuietScratch scratch(std::chrono::seconds(2));
  auto stopping = [this] {
    std::lock_guard lock(stop_mu_);
    return stop_;
  };
  while (!stopping()) {
    const std::vector<std::shared_ptr<PartitionReplica>> replicas = Replicas();
    if (replicas.empty()) {
      sub.reset();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    uint64_t need = UINT64_MAX;
    for (const auto& r : replicas) need = std::min(need, r->applied() + 1);
    // A partition that needs an entry the reader has passed (a new one): read again from
    // there; the others skip what they have.
    if (!sub || need <= passed) {
      sub.reset();
      Result<LiveSubscription> opened = OpenLogReader(*nats_, need, false);
      if (!opened.ok()) {
        spdlog::warn("event=cluster_log_open_failed reason=\"{}\"", opened.status().message());
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        continue;
      }
      sub = std::move(opened).value();
      passed = need - 1;
    }
    natsMsg* raw = nullptr;
    const natsStatus st = natsSubscription_NextMsg(&raw, sub.get(), 100);
    if (st == NATS_TIMEOUT) {
      scratch.Quiet(std::chrono::steady_clock::now());
      continue;
    }
    if (st != NATS_OK) {
      spdlog::warn("event=cluster_log_read_failed reason=\"{}\"", natsStatus_GetText(st));
      sub.reset();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      continue;
    }
    NatsPtr<natsMsg> msg(raw);
    const std::optional<uint64_t> entry = EntrySequence(msg.get());
    if (!entry) continue;
    const uint64_t sequence = *entry;
    // Only the partitions that have every entry this reader delivered before this one.
    std::vector<std::shared_ptr<PartitionReplica>> to;
    for (const auto& r : replicas) {
      const uint64_t applied = r->applied();
      if (applied >= passed && applied < sequence) to.push_back(r);
    }
    passed = sequence;
    Dispatch(sequence, msg.get(), to);
    // Entries for other partitions only use no scratch: the thread is as quiet as on a timeout.
    if (!to.empty()) {
      scratch.Worked(std::chrono::steady_clock::now());
    } else {
      scratch.Quiet(std::chrono::steady_clock::now());
    }
    QueueCheckpoints(to);
  }
}

void ClusterNode::QueueCheckpoints(const std::vector<std::shared_ptr<PartitionReplica>>& to) {
  for (const auto& r : to) {
    {
      // A partition on its way to another owner is checkpointed by that owner.
      std::lock_guard lock(mu_);
      if (leaving_.count(r->key()) != 0) continue;
    }
    std::optional<PartitionCheckpoint> c =
        r->CheckpointIfDue(config_.checkpoint_scans, config_.trim_lag_entries);
    if (!c) continue;
    std::lock_guard lock(checkpoint_mu_);
    pending_checkpoints_.insert_or_assign(r->key(), std::move(*c));
    checkpoint_cv_.notify_one();
  }
}

void ClusterNode::WriteCheckpoints() {
  for (;;) {
    PartitionKey key;
    PartitionCheckpoint c;
    {
      std::unique_lock lock(checkpoint_mu_);
      checkpoint_cv_.wait_for(lock, std::chrono::milliseconds(200),
                              [this] { return !pending_checkpoints_.empty(); });
      {
        std::lock_guard stop(stop_mu_);
        if (stop_) return;
      }
      if (pending_checkpoints_.empty()) continue;
      auto first = pending_checkpoints_.begin();
      key = first->first;
      c = std::move(first->second);
      pending_checkpoints_.erase(first);
    }
    const auto t0 = std::chrono::steady_clock::now();
    const Status s = WriteCheckpoint(*nats_, *trust_, key, c);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s.ok()) {
      spdlog::info(
          "event=partition_checkpointed partition={} log_sequence={} tiles={} "
          "seconds={:.3f}",
          PartitionName(key), c.log_sequence, c.tiles.size(), seconds);
    } else {
      spdlog::warn("event=partition_checkpoint_failed partition={} reason=\"{}\"",
                   PartitionName(key), s.message());
    }
  }
}

void ClusterNode::Dispatch(uint64_t sequence, natsMsg* msg,
                           const std::vector<std::shared_ptr<PartitionReplica>>& to,
                           const Revisions* revisions) {
  if (to.empty()) return;  // an entry read again for other partitions: nothing to do here
  // Not appended by a shard: passed, applied nowhere, no robot's sequence recorded. (A
  // rebuild's replay passes it again without counting it twice.)
  if (Status trusted = VerifyEntry(*trust_, msg, /*headers_only=*/false); !trusted.ok()) {
    if (revisions == nullptr) {
      trust_->Refuse(Untrusted::kLogEntry,
                     "log entry " + std::to_string(sequence) + ": " + trusted.message());
    }
    for (const auto& r : to) r->Apply(sequence, nullptr);
    return;
  }
  Result<LogEntryHeader> header = ReadEntryHeader(msg);
  if (header.ok() && header->kind != LogEntryHeader::Kind::kScan) {
    DispatchChange(sequence, msg, *header, to, revisions);
    return;
  }
  // A scan a correction revised (in a rebuild's replay): its corrected pose, or not at all.
  const Revision* revision = nullptr;
  if (revisions != nullptr) {
    auto it = revisions->find(sequence);
    if (it != revisions->end()) revision = &it->second;
  }
  std::vector<bool> integrate(to.size(), false);
  bool any = false;
  if (!header.ok()) {
    spdlog::error("event=log_entry_skipped sequence={} reason=\"{}\"", sequence,
                  header.status().message());
  } else {
    for (size_t i = 0; i < to.size(); ++i) {
      // Admitted even when removed: a removal changes no robot's sequence.
      const bool admitted = to[i]->Admit(sequence, *header, revision != nullptr);
      integrate[i] = admitted && (revision == nullptr || !revision->removed);
      any = integrate[i] || any;
    }
  }
  PreparedScan prepared;
  bool ready = false;
  if (any) {
    const size_t first = static_cast<size_t>(std::find(integrate.begin(), integrate.end(), true) -
                                             integrate.begin());
    Result<std::string> payload = ScanPayload(sequence, msg, to[first]->key());
    // Out of reach only when the node stops: the entry is left unapplied, not passed without
    // its scan (nothing of this node's partitions outlives it).
    if (payload.status().code() == Status::Code::kUnavailable) return;
    v1::Scan scan;
    Status s = payload.status();
    if (s.ok() && !scan.ParseFromString(*payload)) {
      s = Status::DataLoss("the scan does not decode");
    } else if (s.ok()) {
      s = prepare_(scan, revision != nullptr ? &revision->pose : nullptr, &prepared);
    }
    ready = s.ok();
    if (!ready) {
      spdlog::error("event=log_entry_skipped sequence={} reason=\"{}\"", sequence, s.message());
    }
  }
  for (size_t i = 0; i < to.size(); ++i) {
    to[i]->Apply(sequence, integrate[i] && ready ? &prepared : nullptr);
  }
}

Result<std::string> ClusterNode::ScanPayload(uint64_t sequence, natsMsg* msg, PartitionKey p) {
  const std::optional<RegionKey> region =
      regions_->enabled() ? std::optional(RegionOf(p, regions_->region_partitions()))
                          : std::nullopt;
  for (int attempt = 1;; ++attempt) {
    Result<std::string> payload = EntryPayload(*nats_, msg, region);
    if (payload.ok() || payload.status().code() != Status::Code::kUnavailable) return payload;
    // Passing the entry would leave the partitions without the scan for good: wait for it.
    spdlog::warn("event=region_copy_unavailable sequence={} attempt={} reason=\"{}\"", sequence,
                 attempt, payload.status().message());
    std::unique_lock lock(stop_mu_);
    if (stop_cv_.wait_for(lock, std::chrono::milliseconds(500), [this] { return stop_; })) {
      return payload;
    }
  }
}

void ClusterNode::DispatchChange(uint64_t sequence, natsMsg* msg, const LogEntryHeader& header,
                                 const std::vector<std::shared_ptr<PartitionReplica>>& to,
                                 const Revisions* revisions) {
  using Kind = LogEntryHeader::Kind;
  if (header.kind == Kind::kImport) {
    std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> tiles;
    const std::string manifest(natsMsg_GetData(msg),
                               static_cast<size_t>(natsMsg_GetDataLength(msg)));
    Result<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> read =
        ReadImportTiles(*nats_, manifest, params_);
    if (read.ok()) {
      tiles = std::move(read).value();
    } else {
      spdlog::error("event=log_entry_skipped sequence={} reason=\"import: {}\"", sequence,
                    read.status().message());
    }
    for (const auto& r : to) r->ApplyImport(sequence, tiles);
  } else if (header.kind == Kind::kRetire) {
    for (const auto& r : to) r->ApplyRetire(sequence, header.robot_id);
  } else if (header.kind == Kind::kClear) {
    v1::CellBox cells;
    CellBox box;  // empty: nothing is cleared, the entry is passed
    if (!cells.ParseFromArray(natsMsg_GetData(msg), natsMsg_GetDataLength(msg))) {
      spdlog::error("event=log_entry_skipped sequence={} reason=\"the clear does not decode\"",
                    sequence);
    } else {
      box = {{cells.min_x(), cells.min_y()}, {cells.max_x(), cells.max_y()}};
    }
    for (const auto& r : to) r->ApplyClear(sequence, box);
  } else if (header.kind == Kind::kCorrect) {
    const std::vector<TileKey> affected = CorrectionAffected(
        std::string_view(natsMsg_GetData(msg), static_cast<size_t>(natsMsg_GetDataLength(msg))));
    if (revisions != nullptr) {
      // A rebuild's replay: an earlier correction's revisions are in `revisions` already; its
      // stamps are given again.
      for (const auto& r : to) r->ApplyStamp(sequence, affected);
    } else {
      ApplyCorrection(sequence, header, affected, to);
    }
  } else if (revisions != nullptr) {
    // A rebuild's replay: an export's copies were taken when it was first read.
    for (const auto& r : to) r->Apply(sequence, nullptr);
  } else if (header.kind == Kind::kExport) {
    for (const auto& r : to) r->ApplyExport(sequence);
  } else {
    for (const auto& r : to) r->Apply(sequence, nullptr);  // a refusal: nothing changes
  }
}

std::pair<uint64_t, uint64_t> ClusterNode::NatsReceived() const {
  natsStatistics* stats = nullptr;
  uint64_t messages = 0, bytes = 0;
  if (natsStatistics_Create(&stats) == NATS_OK &&
      natsConnection_GetStats(nats_->connection(), stats) == NATS_OK) {
    natsStatistics_GetCounts(stats, &messages, &bytes, nullptr, nullptr, nullptr);
  }
  natsStatistics_Destroy(stats);
  return {bytes, messages};
}

ClusterStatus ClusterNode::Describe() const {
  ClusterStatus s;
  s.node = config_.node;
  std::lock_guard lock(mu_);
  s.live_nodes = live_;
  s.partitions_known = partitions_known_;
  for (const auto& [p, r] : replicas_) s.replicas.push_back(r->Stats());
  return s;
}

}  // namespace bgkmap::cluster
