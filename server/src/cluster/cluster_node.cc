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
  if (Status s = EnsureLogStream(**nats, log); !s.ok()) return s;
  MembershipOptions mo;
  mo.node = config.node;
  mo.replicas = static_cast<int>(config.replicas);
  mo.lease_s = config.lease_s;
  Result<std::unique_ptr<Membership>> members = Membership::Open(**nats, mo, params_yaml);
  if (!members.ok()) return members.status();
  std::unique_ptr<ClusterNode> node(new ClusterNode(
      config, params, std::move(prepare), std::move(nats).value(), std::move(members).value()));
  if (Status s = node->members_->Heartbeat(); !s.ok()) return s;
  node->Rebalance();
  node->loop_ = std::thread([n = node.get()] { n->Run(); });
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
  std::lock_guard lock(mu_);
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
  std::unique_lock lock(stop_mu_);
  while (!stop_cv_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    if (Status s = members_->Heartbeat(); !s.ok()) {
      spdlog::warn("event=cluster_heartbeat_failed reason=\"{}\"", s.message());
    }
    Rebalance();
    lock.lock();
  }
}

void ClusterNode::Rebalance() {
  Result<std::vector<std::string>> live = members_->LiveNodes();
  Result<std::vector<PartitionKey>> partitions = members_->Partitions();
  if (!live.ok() || !partitions.ok()) {
    spdlog::warn("event=cluster_membership_unreadable reason=\"{}\"",
                 (!live.ok() ? live.status() : partitions.status()).message());
    return;
  }
  // A node always counts itself: its own key may lag its first heartbeat.
  if (std::find(live->begin(), live->end(), config_.node) == live->end()) {
    live->push_back(config_.node);
    std::sort(live->begin(), live->end());
  }
  const auto now = std::chrono::steady_clock::now();
  const auto grace = std::chrono::milliseconds(static_cast<int64_t>(config_.lease_s * 2000));
  std::vector<std::unique_ptr<PartitionReplica>> stopped;
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
      Result<std::unique_ptr<PartitionReplica>> r =
          PartitionReplica::Start(*nats_, layout_, p, params_, prepare_);
      if (!r.ok()) {
        spdlog::warn("event=partition_start_failed partition={} reason=\"{}\"", PartitionName(p),
                     r.status().message());
        continue;
      }
      spdlog::info("event=partition_taken partition={} node={}", PartitionName(p), config_.node);
      replicas_[p] = std::move(r).value();
    } else if (running) {
      auto [it, is_new] = leaving_.try_emplace(p, now);
      if (now - it->second < grace) continue;
      spdlog::info("event=partition_released partition={} node={}", PartitionName(p), config_.node);
      stopped.push_back(std::move(replicas_[p]));
      replicas_.erase(p);
      leaving_.erase(it);
    }
  }
  stopped.clear();  // outside the lock: a replica's stop waits for its threads
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
