#include "cluster/cluster_node.h"

#include <spdlog/spdlog.h>

#include <sstream>

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

}  // namespace

ClusterNode::ClusterNode(const ClusterConfig& config, const MapParams& params, ScanPreparer prepare,
                         std::unique_ptr<NatsClient> nats, std::unique_ptr<Membership> members)
    : config_(config),
      params_(params),
      prepare_(std::move(prepare)),
      layout_(params, static_cast<int>(config.partition_tiles)),
      nats_(std::move(nats)),
      members_(std::move(members)) {
  // A takeover waits for the lease to expire, then for the new owner to read the log.
  reads_ = std::make_unique<ClusterReads>(*nats_, layout_, *members_, params_,
                                          static_cast<int64_t>(config.lease_s * 1000) + 10000);
}

Result<std::unique_ptr<ClusterNode>> ClusterNode::Start(const ClusterConfig& config,
                                                        const MapParams& params,
                                                        const std::string& params_yaml,
                                                        ScanPreparer prepare) {
  Result<std::unique_ptr<NatsClient>> nats =
      NatsClient::Connect(SplitServers(config.nats), "bgkmapd-" + config.node);
  if (!nats.ok()) return nats.status();
  LogStreamOptions log;
  log.replicas = static_cast<int>(config.replicas);
  log.dedupe_window_s = config.dedupe_window_s;
  // NATS may be starting with us (a clustered JetStream answers once it has elected its meta
  // leader): wait for it a while rather than fail the start.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  for (Status s = EnsureLogStream(**nats, log); !s.ok(); s = EnsureLogStream(**nats, log)) {
    if (s.code() == Status::Code::kFailedPrecondition ||
        std::chrono::steady_clock::now() > deadline) {
      return s;
    }
    spdlog::info("event=cluster_waiting_for_jetstream reason=\"{}\"", s.message());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  MembershipOptions mo;
  mo.node = config.node;
  mo.replicas = static_cast<int>(config.replicas);
  mo.lease_s = config.lease_s;
  Result<std::unique_ptr<Membership>> members = Membership::Open(**nats, mo, params_yaml);
  if (!members.ok()) return members.status();
  std::unique_ptr<ClusterNode> node(new ClusterNode(
      config, params, std::move(prepare), std::move(nats).value(), std::move(members).value()));
  if (Status s = node->members_->Heartbeat(); !s.ok()) return s;
  node->loop_ = std::thread([n = node.get()] { n->Run(); });
  node->reader_ = std::thread([n = node.get()] { n->ReadLog(); });
  spdlog::info("event=cluster_joined node={} partition_tiles={} halo_cells={}", config.node,
               config.partition_tiles, node->layout_.halo_cells());
  return node;
}

ClusterNode::~ClusterNode() {
  {
    std::lock_guard lock(stop_mu_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (loop_.joinable()) loop_.join();
  if (reader_.joinable()) reader_.join();
  std::lock_guard lock(mu_);
  for (auto& [p, r] : replicas_) r->BeginStop();
  replicas_.clear();
}

Result<Appended> ClusterNode::Append(const v1::Scan& scan, const PreparedScan& prepared) {
  // Refused before anything is recorded: the log takes messages up to the servers' max_payload.
  if (static_cast<int64_t>(scan.ByteSizeLong()) + 1024 > nats_->max_payload()) {
    return Status::OutOfRange("scan: " + std::to_string(scan.ByteSizeLong()) +
                              " bytes exceed the NATS servers' max_payload of " +
                              std::to_string(nats_->max_payload()) +
                              " bytes (nats-server: max_payload, up to 64 MB)");
  }
  const std::vector<PartitionKey> touched = layout_.Touched(prepared);
  // Recorded before the append: an owner that learns of the partition reads the log from its
  // start, so it finds the scan whenever it learns.
  for (PartitionKey p : touched) {
    if (Status s = members_->AddPartition(p); !s.ok()) return Status::Unavailable(s.message());
  }
  return AppendScan(*nats_, scan, touched);
}

void ClusterNode::Run() {
  const auto period = std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 250));
  // Partitions are taken only after one lease: by then this node has seen every live node's
  // heartbeat, so nodes started together split the partitions instead of each taking all.
  const auto first_rebalance =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(
                                             static_cast<int64_t>(config_.lease_s * 1000));
  std::unique_lock lock(stop_mu_);
  while (!stop_cv_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    if (Status s = members_->Heartbeat(); !s.ok()) {
      spdlog::warn("event=cluster_heartbeat_failed reason=\"{}\"", s.message());
    }
    if (std::chrono::steady_clock::now() >= first_rebalance) Rebalance();
    lock.lock();
  }
}

void ClusterNode::Rebalance() {
  std::vector<std::string> live_nodes = members_->LiveNodes();
  const std::vector<PartitionKey> known = members_->Partitions();
  std::vector<std::string>* live = &live_nodes;
  const std::vector<PartitionKey>* partitions = &known;
  // A node always counts itself: its own key may lag its first heartbeat.
  if (std::find(live->begin(), live->end(), config_.node) == live->end()) {
    live->push_back(config_.node);
    std::sort(live->begin(), live->end());
  }
  const auto now = std::chrono::steady_clock::now();
  const auto grace = std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 2000));
  std::vector<std::shared_ptr<PartitionReplica>> stopped;
  {
    std::lock_guard lock(mu_);
    live_ = *live;
    partitions_known_ = partitions->size();
  }
  for (PartitionKey p : *partitions) {
    const bool mine = Membership::OwnerOf(p, *live) == config_.node;
    std::lock_guard lock(mu_);
    const bool running = replicas_.count(p) != 0;
    if (mine) {
      leaving_.erase(p);
      if (running) continue;
      // It serves once it has read the log up to its end as of now.
      Result<uint64_t> end = LastSequence(*nats_);
      Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
      if (!end.ok() || !map.ok()) {
        spdlog::warn("event=partition_start_failed partition={} reason=\"{}\"", PartitionName(p),
                     (!end.ok() ? end.status() : map.status()).message());
        continue;
      }
      spdlog::info("event=partition_taken partition={} node={}", PartitionName(p), config_.node);
      replicas_[p] =
          std::make_shared<PartitionReplica>(*nats_, layout_, p, std::move(map).value(), *end);
    } else if (running) {
      auto [it, is_new] = leaving_.try_emplace(p, now);
      if (now - it->second < grace) continue;
      spdlog::info("event=partition_released partition={} node={}", PartitionName(p), config_.node);
      replicas_[p]->BeginStop();
      stopped.push_back(std::move(replicas_[p]));
      replicas_.erase(p);
      leaving_.erase(it);
    }
  }
  stopped.clear();  // outside the lock: a replica's stop waits for its threads
}

std::vector<std::shared_ptr<PartitionReplica>> ClusterNode::Replicas() const {
  std::lock_guard lock(mu_);
  std::vector<std::shared_ptr<PartitionReplica>> out;
  for (const auto& [p, r] : replicas_) out.push_back(r);
  return out;
}

void ClusterNode::ReadLog() {
  NatsPtr<natsSubscription> sub;
  uint64_t passed = 0;  // the last entry the current reader delivered (its start - 1 at first)
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
      jsSubOptions so;
      jsSubOptions_Init(&so);
      so.Ordered = true;  // in the log's order, recreated by nats.c after a failure
      so.Config.DeliverPolicy = js_DeliverByStartSequence;
      so.Config.OptStartSeq = need;
      natsSubscription* raw = nullptr;
      jsErrCode jerr = static_cast<jsErrCode>(0);
      const natsStatus st =
          js_SubscribeSync(&raw, nats_->jetstream(), kScanSubject, nullptr, &so, &jerr);
      if (st != NATS_OK) {
        spdlog::warn("event=cluster_log_open_failed reason=\"{}\"",
                     NatsStatus(st, "read the log", jerr).message());
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        continue;
      }
      sub.reset(raw);
      passed = need - 1;
    }
    natsMsg* raw = nullptr;
    const natsStatus st = natsSubscription_NextMsg(&raw, sub.get(), 100);
    if (st == NATS_TIMEOUT) continue;
    if (st != NATS_OK) {
      spdlog::warn("event=cluster_log_read_failed reason=\"{}\"", natsStatus_GetText(st));
      sub.reset();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      continue;
    }
    NatsPtr<natsMsg> msg(raw);
    jsMsgMetaData* meta_raw = nullptr;
    if (natsMsg_GetMetaData(&meta_raw, msg.get()) != NATS_OK) continue;
    NatsPtr<jsMsgMetaData> meta(meta_raw);
    const uint64_t sequence = meta->Sequence.Stream;
    // Only the partitions that have every entry this reader delivered before this one.
    std::vector<std::shared_ptr<PartitionReplica>> to;
    for (const auto& r : replicas) {
      const uint64_t applied = r->applied();
      if (applied >= passed && applied < sequence) to.push_back(r);
    }
    passed = sequence;
    Dispatch(sequence, msg.get(), to);
  }
}

void ClusterNode::Dispatch(uint64_t sequence, natsMsg* msg,
                           const std::vector<std::shared_ptr<PartitionReplica>>& to) {
  Result<LogEntryHeader> header = ReadEntryHeader(msg);
  std::vector<bool> integrate(to.size(), false);
  bool any = false;
  if (!header.ok()) {
    spdlog::error("event=log_entry_skipped sequence={} reason=\"{}\"", sequence,
                  header.status().message());
  } else {
    for (size_t i = 0; i < to.size(); ++i)
      any = (integrate[i] = to[i]->Admit(sequence, *header)) || any;
  }
  PreparedScan prepared;
  bool ready = false;
  if (any) {
    v1::Scan scan;
    Status s = Status::Ok();
    if (!scan.ParseFromArray(natsMsg_GetData(msg), natsMsg_GetDataLength(msg))) {
      s = Status::DataLoss("the scan does not decode");
    } else {
      s = prepare_(scan, &prepared);
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
