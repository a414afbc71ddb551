#include "cluster/membership.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "cluster/region_streams.h"

namespace bgkmap::cluster {
namespace {

Result<NatsPtr<kvStore>> OpenBucket(const NatsClient& nats, const char* name, int replicas,
                                    int64_t ttl_ns) {
  kvConfig cfg;
  kvConfig_Init(&cfg);
  cfg.Bucket = name;
  cfg.History = 1;
  cfg.Replicas = replicas;
  cfg.StorageType = js_FileStorage;
  cfg.TTL = ttl_ns;  // nats.c 3.4: nanoseconds
  kvStore* kv = nullptr;
  const natsStatus created = js_CreateKeyValue(&kv, nats.jetstream(), &cfg);
  if (created == NATS_OK) return NatsPtr<kvStore>(kv);
  const std::string why = nats_GetLastError(nullptr);
  // Made by another node first.
  if (js_KeyValue(&kv, nats.jetstream(), name) != NATS_OK) {
    return NatsStatus(created, std::string("cluster: key-value bucket ") + name + " (" + why + ")");
  }
  return NatsPtr<kvStore>(kv);
}

uint64_t Fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  // A final mix: FNV's low bits alone spread nearby names poorly.
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  return h;
}

// The parameters as recorded: the YAML, then (with a key) a comment line holding its HMAC.
constexpr const char* kParamsMacLine = "\n# bgkmap-mac ";

std::string SignedParams(const ClusterTrust& trust, const std::string& yaml) {
  if (!trust.keyed()) return yaml;
  return yaml + kParamsMacLine + trust.Sign({"bgkmap-params-1", yaml});
}

// The YAML of a recorded value whose HMAC verifies (nullopt: not recorded by a shard).
std::optional<std::string> TrustedParams(const ClusterTrust& trust, const std::string& value) {
  if (!trust.keyed()) return value;
  const size_t at = value.rfind(kParamsMacLine);
  if (at == std::string::npos) return std::nullopt;
  std::string yaml = value.substr(0, at);
  const std::string mac = value.substr(at + std::string_view(kParamsMacLine).size());
  if (!trust.Verify(mac, {"bgkmap-params-1", yaml})) return std::nullopt;
  return yaml;
}

std::string FirstDifference(const std::string& a, const std::string& b) {
  std::istringstream sa(a), sb(b);
  std::string la, lb;
  while (true) {
    const bool ga = static_cast<bool>(std::getline(sa, la));
    const bool gb = static_cast<bool>(std::getline(sb, lb));
    if (!ga && !gb) return "";
    if (!ga || !gb || la != lb) return "this node has '" + la + "', the cluster '" + lb + "'";
  }
}

}  // namespace

Result<std::unique_ptr<Membership>> Membership::Open(const NatsClient& nats,
                                                     const MembershipOptions& options,
                                                     const std::string& params_yaml,
                                                     const ClusterTrust& trust) {
  Result<NatsPtr<kvStore>> cluster = OpenBucket(nats, "bgkmap_cluster", options.replicas, 0);
  if (!cluster.ok()) return cluster.status();
  // The first node sets the parameters; every other one must have the same.
  const std::string mine = SignedParams(trust, params_yaml);
  uint64_t rev = 0;
  natsStatus st =
      kvStore_Create(&rev, cluster->get(), "params", mine.data(), static_cast<int>(mine.size()));
  if (st != NATS_OK) {
    kvEntry* e = nullptr;
    st = kvStore_Get(&e, cluster->get(), "params");
    NatsPtr<kvEntry> entry(e);
    if (st != NATS_OK) return NatsStatus(st, "cluster: read the cluster's map parameters");
    std::optional<std::string> theirs =
        TrustedParams(trust, std::string(static_cast<const char*>(kvEntry_Value(entry.get())),
                                         static_cast<size_t>(kvEntry_ValueLen(entry.get()))));
    if (!theirs) {
      // Not recorded by a shard: ours replace it.
      trust.Refuse(Untrusted::kMembership, "the cluster's parameters are not signed");
      st = kvStore_Put(&rev, cluster->get(), "params", mine.data(), static_cast<int>(mine.size()));
      if (st != NATS_OK) return NatsStatus(st, "cluster: record the map parameters");
      theirs = params_yaml;
    }
    if (*theirs != params_yaml) {
      return Status::FailedPrecondition("cluster: the map parameters differ from the cluster's: " +
                                        FirstDifference(params_yaml, *theirs));
    }
  }
  Result<NatsPtr<kvStore>> nodes = OpenBucket(nats, "bgkmap_nodes", options.replicas,
                                              static_cast<int64_t>(options.lease_s * 1e9));
  if (!nodes.ok()) return nodes.status();
  Result<NatsPtr<kvStore>> partitions = OpenBucket(nats, "bgkmap_partitions", options.replicas, 0);
  if (!partitions.ok()) return partitions.status();
  std::unique_ptr<Membership> m(new Membership(options, trust, nats.connection(),
                                               std::move(nodes).value().release(),
                                               std::move(partitions).value().release()));
  if (Status s = m->StartWatching(); !s.ok()) return s;
  return m;
}

Membership::~Membership() {
  stop_ = true;
  for (std::thread& t : watchers_) t.join();
}

Status Membership::StartWatching() {
  for (const bool nodes : {true, false}) {
    kvStore* bucket = nodes ? nodes_.get() : partitions_.get();
    watchers_.emplace_back([this, bucket, nodes] { Watch(bucket, nodes); });
  }
  return Status::Ok();
}

void Membership::Watch(kvStore* bucket, bool nodes) {
  kvWatcher* watcher = nullptr;
  while (!stop_ && watcher == nullptr) {
    kvWatchOptions o;
    kvWatchOptions_Init(&o);
    o.MetaOnly = !trust_.keyed();  // without a key the keys are the news; with one, the values
    if (kvStore_WatchAll(&watcher, bucket, &o) != NATS_OK) {
      watcher = nullptr;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }
  while (!stop_) {
    kvEntry* raw = nullptr;
    const natsStatus st = kvWatcher_Next(&raw, watcher, 100);
    if (st != NATS_OK || raw == nullptr) continue;  // timeout, or "initial values done"
    NatsPtr<kvEntry> entry(raw);
    const std::string key = kvEntry_Key(raw);
    const bool put = kvEntry_Operation(raw) == kvOp_Put;
    // With a key, a deletion is no shard's (a node's key only expires) and a put counts once
    // its HMAC verifies.
    if ((!put && trust_.keyed()) ||
        (put && !(nodes ? TrustedHeartbeat(raw) : TrustedPartition(raw)))) {
      trust_.Refuse(Untrusted::kMembership,
                    std::string(nodes ? "node '" : "partition '") + key +
                        (put ? "': not signed by a shard" : "': deleted by someone"));
      continue;
    }
    std::lock_guard lock(mu_);
    if (nodes) {
      if (put) {
        seen_[key] = std::chrono::steady_clock::now();
      } else {
        seen_.erase(key);
      }
    } else if (std::optional<PartitionKey> p = ParsePartitionName(key); p && put) {
      known_.insert(*p);
    }
  }
  if (watcher != nullptr) {
    kvWatcher_Stop(watcher);                 // its subscription's interest removed
    natsConnection_FlushTimeout(nc_, 2000);  // then freed: QuiesceSubscription's reason
    kvWatcher_Destroy(watcher);
  }
}

bool Membership::TrustedHeartbeat(kvEntry* entry) const {
  if (!trust_.keyed()) return true;
  const std::string value(static_cast<const char*>(kvEntry_Value(entry)),
                          static_cast<size_t>(kvEntry_ValueLen(entry)));
  const size_t space = value.find(' ');
  if (space == std::string::npos) return false;
  const std::string time = value.substr(0, space);
  if (!trust_.Verify(value.substr(space + 1), {"bgkmap-node-1", kvEntry_Key(entry), time})) {
    return false;
  }
  int64_t signed_ns = 0;
  if (auto [end, ec] = std::from_chars(time.data(), time.data() + time.size(), signed_ns);
      ec != std::errc() || end != time.data() + time.size()) {
    return false;
  }
  const auto lease = std::chrono::nanoseconds(static_cast<int64_t>(options_.lease_s * 1e9));
  return ClusterTrust::StoredInTime(signed_ns, kvEntry_Created(entry), lease);
}

std::string Membership::PartitionValue(const std::string& name) const {
  return trust_.keyed() ? trust_.Sign({"bgkmap-partition-1", name}) : "1";
}

bool Membership::TrustedPartition(kvEntry* entry) const {
  if (!trust_.keyed()) return true;
  const std::string value(static_cast<const char*>(kvEntry_Value(entry)),
                          static_cast<size_t>(kvEntry_ValueLen(entry)));
  return trust_.Verify(value, {"bgkmap-partition-1", kvEntry_Key(entry)});
}

Status Membership::Heartbeat() {
  uint64_t rev = 0;
  std::string value = "alive";
  if (trust_.keyed()) {
    const std::string time = std::to_string(ClusterTrust::NowNs());
    value = time + " " + trust_.Sign({"bgkmap-node-1", options_.node, time});
  }
  const natsStatus st = kvStore_PutString(&rev, nodes_.get(), options_.node.c_str(), value.c_str());
  if (st != NATS_OK) return NatsStatus(st, "cluster: heartbeat");
  return Status::Ok();
}

std::vector<std::string> Membership::LiveNodes() const {
  const auto now = std::chrono::steady_clock::now();
  const auto lease = std::chrono::duration<double>(options_.lease_s);
  std::vector<std::string> out;
  std::lock_guard lock(mu_);
  for (const auto& [node, seen] : seen_) {
    if (now - seen < lease) out.push_back(node);
  }
  return out;
}

std::vector<PartitionKey> Membership::Partitions() const {
  std::lock_guard lock(mu_);
  return {known_.begin(), known_.end()};
}

Status Membership::AddPartition(PartitionKey p) {
  {
    std::lock_guard lock(mu_);
    if (known_.count(p) != 0) return Status::Ok();
  }
  const std::string name = PartitionName(p);
  // Through the bucket's leader election after a NATS server's death (no responders for a
  // while), as the log's appends are.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  const std::string value = PartitionValue(name);
  for (;;) {
    uint64_t rev = 0;
    const natsStatus st =
        kvStore_CreateString(&rev, partitions_.get(), name.c_str(), value.c_str());
    if (st == NATS_OK) break;
    // Another node recorded it first: fine, if it is really there (a record not signed by a
    // shard is replaced: the value is the same whoever writes it).
    Result<bool> has = HasPartition(p);
    if (has.ok() && *has) break;
    if (has.ok() &&
        kvStore_PutString(&rev, partitions_.get(), name.c_str(), value.c_str()) == NATS_OK) {
      break;
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      return has.ok() ? NatsStatus(st, "cluster: record partition " + name) : has.status();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  std::lock_guard lock(mu_);
  known_.insert(p);
  return Status::Ok();
}

Result<std::vector<PartitionKey>> Membership::ListRecordedPartitions() const {
  kvKeysList keys;
  const natsStatus st =
      RetryWhileElecting([&] { return kvStore_Keys(&keys, partitions_.get(), nullptr); }, 5000);
  if (st == NATS_NOT_FOUND) return std::vector<PartitionKey>();  // none yet
  if (st != NATS_OK) return NatsStatus(st, "cluster: list the partitions");
  std::vector<PartitionKey> out;
  for (int i = 0; i < keys.Count; ++i) {
    if (std::optional<PartitionKey> p = ParsePartitionName(keys.Keys[i])) out.push_back(*p);
  }
  kvKeysList_Destroy(&keys);
  std::sort(out.begin(), out.end());
  return out;
}

Result<bool> Membership::HasPartition(PartitionKey p) const {
  {
    std::lock_guard lock(mu_);
    if (known_.count(p) != 0) return true;
  }
  kvEntry* e = nullptr;
  const natsStatus st = kvStore_Get(&e, partitions_.get(), PartitionName(p).c_str());
  NatsPtr<kvEntry> entry(e);
  if (st == NATS_NOT_FOUND) return false;
  if (st != NATS_OK) return NatsStatus(st, "cluster: look up partition " + PartitionName(p));
  if (!TrustedPartition(entry.get())) {
    trust_.Refuse(Untrusted::kMembership, "partition '" + PartitionName(p) + "': not signed");
    return false;
  }
  return true;
}

std::string Membership::OwnerOf(PartitionKey p, const std::vector<std::string>& live,
                                int region_partitions) {
  std::string best;
  uint64_t best_hash = 0;
  const std::string name = region_partitions > 0
                               ? "region/" + RegionName(RegionOf(p, region_partitions))
                               : PartitionName(p);
  for (const std::string& node : live) {
    const uint64_t h = Fnv1a(node + "/" + name);
    if (best.empty() || h > best_hash) {
      best = node;
      best_hash = h;
    }
  }
  return best;
}

}  // namespace bgkmap::cluster
