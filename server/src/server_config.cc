#include "bgkmap/server/server_config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/server/host_port.h"

namespace bgkmap {
namespace {

// One `server:` key: how to read it, how to write it.
struct ServerKey {
  std::string name;
  std::function<Status(const YAML::Node&, ServerConfig&)> read;
  std::function<YAML::Node(const ServerConfig&)> write;
};

// `key` is the key's full name ("server.x", "storage.y"): every message starts with it.
template <typename T>
Status ReadScalar(const YAML::Node& node, const std::string& key, T* out) {
  try {
    T value = node.as<T>();
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(value)) {
        return Status::InvalidArgument(key + ": must be finite");
      }
    }
    *out = value;
    return Status::Ok();
  } catch (const YAML::Exception&) {
    std::string shown = node.IsScalar() ? node.Scalar() : "(not a scalar)";
    return Status::InvalidArgument(key + ": '" + shown + "' is not a valid value");
  }
}

// Unsigned keys go through int64 so that "-1" is an error instead of a huge number.
template <typename T>
Status ReadUnsigned(const YAML::Node& node, const std::string& key, T* out) {
  int64_t v = 0;
  if (Status s = ReadScalar(node, key, &v); !s.ok()) return s;
  if (v < 0 || static_cast<uint64_t>(v) > std::numeric_limits<T>::max()) {
    return Status::InvalidArgument(key + ": " + std::to_string(v) + " is out of range");
  }
  *out = static_cast<T>(v);
  return Status::Ok();
}

template <typename T, typename Member>
ServerKey Key(std::string name, Member member, const std::string& section = "server") {
  ServerKey k;
  k.name = name;
  k.read = [full = section + "." + name, member](const YAML::Node& n, ServerConfig& c) {
    if constexpr (std::is_unsigned_v<T> && !std::is_same_v<T, bool>) {
      return ReadUnsigned<T>(n, full, &member(c));
    } else {
      return ReadScalar<T>(n, full, &member(c));
    }
  };
  k.write = [member](const ServerConfig& c) {
    return YAML::Node(member(const_cast<ServerConfig&>(c)));
  };
  return k;
}

// server.*: the listeners, threads, logging and security.
std::vector<ServerKey> ListenerKeys() {
  return {
      Key<std::string>(
          "listen_address", [](ServerConfig & c) -> auto& { return c.listen_address; }),
      Key<int>(
          "worker_threads", [](ServerConfig & c) -> auto& { return c.worker_threads; }),
      Key<int>(
          "query_threads", [](ServerConfig & c) -> auto& { return c.query_threads; }),
      Key<int>(
          "worker_nice", [](ServerConfig & c) -> auto& { return c.worker_nice; }),
      Key<std::vector<int>>(
          "worker_cpus", [](ServerConfig & c) -> auto& { return c.worker_cpus; }),
      Key<int>(
          "malloc_arenas", [](ServerConfig & c) -> auto& { return c.malloc_arenas; }),
      Key<int>(
          "scan_bands", [](ServerConfig & c) -> auto& { return c.scan_bands; }),
      Key<std::string>(
          "log_level", [](ServerConfig & c) -> auto& { return c.log_level; }),
      Key<double>(
          "shutdown_timeout_s", [](ServerConfig & c) -> auto& { return c.shutdown_timeout_s; }),
      Key<std::string>(
          "metrics_address", [](ServerConfig & c) -> auto& { return c.metrics_address; }),
      Key<std::string>(
          "foxglove.address", [](ServerConfig & c) -> auto& { return c.foxglove.address; }),
      Key<std::vector<double>>(
          "foxglove.region", [](ServerConfig & c) -> auto& { return c.foxglove.region; }),
      Key<uint32_t>(
          "foxglove.max_clients", [](ServerConfig & c) -> auto& { return c.foxglove.max_clients; }),
      Key<uint64_t>(
          "foxglove.max_queued_bytes",
          [](ServerConfig & c) -> auto& { return c.foxglove.max_queued_bytes; }),
      Key<uint32_t>(
          "foxglove.max_scan_points",
          [](ServerConfig & c) -> auto& { return c.foxglove.max_scan_points; }),
      Key<std::string>(
          "tls.cert_file", [](ServerConfig & c) -> auto& { return c.tls.cert_file; }),
      Key<std::string>(
          "tls.key_file", [](ServerConfig & c) -> auto& { return c.tls.key_file; }),
      Key<std::string>(
          "tls.client_ca_file", [](ServerConfig & c) -> auto& { return c.tls.client_ca_file; }),
      Key<std::string>(
          "auth.tokens_file", [](ServerConfig & c) -> auto& { return c.auth.tokens_file; }),
      Key<uint32_t>(
          "auth.max_queries_per_token",
          [](ServerConfig & c) -> auto& { return c.auth.max_queries_per_token; }),
      Key<uint32_t>(
          "auth.max_ingest_streams_per_token",
          [](ServerConfig & c) -> auto& { return c.auth.max_ingest_streams_per_token; }),
      Key<uint32_t>(
          "auth.max_watchers_per_token",
          [](ServerConfig & c) -> auto& { return c.auth.max_watchers_per_token; }),
      Key<uint32_t>(
          "auth.max_event_streams_per_token",
          [](ServerConfig & c) -> auto& { return c.auth.max_event_streams_per_token; }),
      Key<bool>(
          "insecure", [](ServerConfig & c) -> auto& { return c.insecure; }),
  };
}

// server.*: the limits on what a client may ask (ServerLimits).
std::vector<ServerKey> LimitKeys() {
  return {
      Key<uint64_t>(
          "max_points_per_scan",
          [](ServerConfig & c) -> auto& { return c.limits.max_points_per_scan; }),
      Key<uint64_t>(
          "max_region_cells", [](ServerConfig & c) -> auto& { return c.limits.max_region_cells; }),
      Key<uint64_t>(
          "max_region_read_cells",
          [](ServerConfig & c) -> auto& { return c.limits.max_region_read_cells; }),
      Key<uint64_t>(
          "max_query_points", [](ServerConfig & c) -> auto& { return c.limits.max_query_points; }),
      Key<uint64_t>(
          "max_path_poses", [](ServerConfig & c) -> auto& { return c.limits.max_path_poses; }),
      Key<uint64_t>(
          "max_correction_scans",
          [](ServerConfig & c) -> auto& { return c.limits.max_correction_scans; }),
      Key<uint64_t>(
          "max_footprint_cells",
          [](ServerConfig & c) -> auto& { return c.limits.max_footprint_cells; }),
      Key<uint64_t>(
          "max_path_check_cells",
          [](ServerConfig & c) -> auto& { return c.limits.max_path_check_cells; }),
      Key<double>(
          "max_coordinate", [](ServerConfig & c) -> auto& { return c.limits.max_coordinate; }),
      Key<double>(
          "quaternion_tolerance",
          [](ServerConfig & c) -> auto& { return c.limits.quaternion_tolerance; }),
      Key<uint32_t>(
          "max_inflight_scans_per_stream",
          [](ServerConfig & c) -> auto& { return c.limits.max_inflight_scans_per_stream; }),
      Key<uint32_t>(
          "max_inflight_unary_scans",
          [](ServerConfig & c) -> auto& { return c.limits.max_inflight_unary_scans; }),
      Key<uint32_t>(
          "max_ingest_streams",
          [](ServerConfig & c) -> auto& { return c.limits.max_ingest_streams; }),
      Key<uint32_t>(
          "max_robots", [](ServerConfig & c) -> auto& { return c.limits.max_robots; }),
      Key<uint32_t>(
          "max_watchers", [](ServerConfig & c) -> auto& { return c.limits.max_watchers; }),
      Key<uint64_t>(
          "max_watch_tiles", [](ServerConfig & c) -> auto& { return c.limits.max_watch_tiles; }),
      Key<uint32_t>(
          "max_concurrent_queries",
          [](ServerConfig & c) -> auto& { return c.limits.max_concurrent_queries; }),
      Key<uint64_t>(
          "max_region_bytes_in_flight",
          [](ServerConfig & c) -> auto& { return c.limits.max_region_bytes_in_flight; }),
      Key<uint64_t>(
          "max_message_bytes",
          [](ServerConfig & c) -> auto& { return c.limits.max_message_bytes; }),
      Key<uint64_t>(
          "region_chunk_bytes",
          [](ServerConfig & c) -> auto& { return c.limits.region_chunk_bytes; }),
      Key<uint64_t>(
          "max_import_bytes", [](ServerConfig & c) -> auto& { return c.limits.max_import_bytes; }),
      Key<uint64_t>(
          "max_sequence_jump",
          [](ServerConfig & c) -> auto& { return c.limits.max_sequence_jump; }),
      Key<double>(
          "ingest_idle_timeout_s",
          [](ServerConfig & c) -> auto& { return c.limits.ingest_idle_timeout_s; }),
      Key<double>(
          "stalled_write_timeout_s",
          [](ServerConfig & c) -> auto& { return c.limits.stalled_write_timeout_s; }),
      Key<double>(
          "import_idle_timeout_s",
          [](ServerConfig & c) -> auto& { return c.limits.import_idle_timeout_s; }),
      Key<double>(
          "max_query_seconds",
          [](ServerConfig & c) -> auto& { return c.limits.max_query_seconds; }),
  };
}

const std::vector<ServerKey>& Keys() {
  static const std::vector<ServerKey> keys = [] {
    std::vector<ServerKey> k = ListenerKeys();
    for (ServerKey& limit : LimitKeys()) k.push_back(std::move(limit));
    return k;
  }();
  return keys;
}

const std::vector<ServerKey>& StorageKeys() {
  static const std::vector<ServerKey> keys = {
      Key<std::string>(
          "data_dir", [](ServerConfig & c) -> auto& { return c.storage.data_dir; }, "storage"),
      Key<std::string>(
          "durability", [](ServerConfig & c) -> auto& { return c.storage.durability; }, "storage"),
      Key<uint32_t>(
          "periodic_sync_ms", [](ServerConfig & c) -> auto& { return c.storage.periodic_sync_ms; },
          "storage"),
      Key<double>(
          "checkpoint_interval_s",
          [](ServerConfig & c) -> auto& { return c.storage.checkpoint_interval_s; }, "storage"),
      Key<uint64_t>(
          "max_memory_mb", [](ServerConfig & c) -> auto& { return c.storage.max_memory_mb; },
          "storage"),
      Key<uint64_t>(
          "dense_tiles_mb", [](ServerConfig & c) -> auto& { return c.storage.dense_tiles_mb; },
          "storage"),
      Key<bool>(
          "verify_on_start", [](ServerConfig & c) -> auto& { return c.storage.verify_on_start; },
          "storage"),
      Key<uint64_t>(
          "min_free_space_mb",
          [](ServerConfig & c) -> auto& { return c.storage.min_free_space_mb; }, "storage"),
      Key<uint64_t>(
          "retention_mb", [](ServerConfig & c) -> auto& { return c.storage.retention_mb; },
          "storage"),
      Key<double>(
          "retention_s", [](ServerConfig & c) -> auto& { return c.storage.retention_s; },
          "storage"),
  };
  return keys;
}

const std::vector<ServerKey>& GeoreferenceKeys() {
  static const std::vector<ServerKey> keys = [] {
    std::vector<ServerKey> k = {Key<std::string>(
        "crs", [](ServerConfig & c) -> auto& { return c.georeference.crs; }, "georeference")};
    ServerKey origin;
    origin.name = "origin";
    origin.read = [](const YAML::Node& n, ServerConfig& c) {
      const std::string key = "georeference.origin";
      if (!n.IsSequence() || n.size() != 3) {
        return Status::InvalidArgument(key + ": expected [easting, northing, height]");
      }
      std::array<double, 3> v{};
      for (size_t i = 0; i < 3; ++i) {
        if (Status s = ReadScalar(n[i], key, &v[i]); !s.ok()) return s;
      }
      c.georeference.origin = v;
      return Status::Ok();
    };
    origin.write = [](const ServerConfig& c) {
      YAML::Node n(YAML::NodeType::Sequence);
      for (double v : c.georeference.origin) n.push_back(v);
      n.SetStyle(YAML::EmitterStyle::Flow);
      return n;
    };
    k.push_back(origin);
    return k;
  }();
  return keys;
}

const std::vector<ServerKey>& ClusterKeys() {
  static const std::vector<ServerKey> keys = {
      Key<std::string>(
          "nats", [](ServerConfig & c) -> auto& { return c.cluster.nats; }, "cluster"),
      Key<std::string>(
          "node", [](ServerConfig & c) -> auto& { return c.cluster.node; }, "cluster"),
      Key<uint32_t>(
          "partition_tiles", [](ServerConfig & c) -> auto& { return c.cluster.partition_tiles; },
          "cluster"),
      Key<uint32_t>(
          "replicas", [](ServerConfig & c) -> auto& { return c.cluster.replicas; }, "cluster"),
      Key<double>(
          "lease_s", [](ServerConfig & c) -> auto& { return c.cluster.lease_s; }, "cluster"),
      Key<double>(
          "dedupe_window_s", [](ServerConfig & c) -> auto& { return c.cluster.dedupe_window_s; },
          "cluster"),
      Key<double>(
          "startup_wait_s", [](ServerConfig & c) -> auto& { return c.cluster.startup_wait_s; },
          "cluster"),
      Key<uint32_t>(
          "checkpoint_scans", [](ServerConfig & c) -> auto& { return c.cluster.checkpoint_scans; },
          "cluster"),
      Key<uint32_t>(
          "trim_lag_entries", [](ServerConfig & c) -> auto& { return c.cluster.trim_lag_entries; },
          "cluster"),
      Key<uint32_t>(
          "region_partitions",
          [](ServerConfig & c) -> auto& { return c.cluster.region_partitions; }, "cluster"),
      Key<std::string>(
          "key_file", [](ServerConfig & c) -> auto& { return c.cluster.key_file; }, "cluster"),
      Key<bool>(
          "insecure", [](ServerConfig & c) -> auto& { return c.cluster.insecure; }, "cluster"),
      Key<std::string>(
          "nats_credentials", [](ServerConfig & c) -> auto& { return c.cluster.nats_credentials; },
          "cluster"),
      Key<std::string>(
          "nats_tls.ca_file", [](ServerConfig & c) -> auto& { return c.cluster.nats_tls.ca_file; },
          "cluster"),
      Key<std::string>(
          "nats_tls.cert_file",
          [](ServerConfig & c) -> auto& { return c.cluster.nats_tls.cert_file; }, "cluster"),
      Key<std::string>(
          "nats_tls.key_file",
          [](ServerConfig & c) -> auto& { return c.cluster.nats_tls.key_file; }, "cluster"),
  };
  return keys;
}

// Keys of a subsection ("tls.cert_file") are read from nested mappings (`tls: {cert_file: ..}`)
// or as one dotted name (--set server.tls.cert_file=...).
Status ReadSection(const YAML::Node& section, const std::string& section_name,
                   const std::vector<ServerKey>& keys, ServerConfig& config,
                   const std::string& prefix = "") {
  if (!section.IsMap()) {
    return Status::InvalidArgument(section_name + (prefix.empty() ? "" : "." + prefix) +
                                   ": must be a mapping of keys");
  }
  for (const auto& entry : section) {
    const std::string name = prefix + entry.first.as<std::string>();
    const ServerKey* key = nullptr;
    bool subsection = false;
    for (const ServerKey& k : keys) {
      if (k.name == name) key = &k;
      if (k.name.rfind(name + ".", 0) == 0) subsection = true;
    }
    if (key == nullptr && subsection) {
      if (entry.second.IsNull()) continue;  // "tls:" alone means defaults
      if (Status s = ReadSection(entry.second, section_name, keys, config, name + "."); !s.ok()) {
        return s;
      }
      continue;
    }
    if (key == nullptr) {
      return Status::InvalidArgument(section_name + "." + name + ": unknown key");
    }
    if (Status s = key->read(entry.second, config); !s.ok()) return s;
  }
  return Status::Ok();
}

// Writes "tls.cert_file" as server: {tls: {cert_file: ...}}.
void WriteKey(YAML::Node section, const std::string& name, const YAML::Node& value) {
  const size_t dot = name.find('.');
  if (dot == std::string::npos) {
    section[name] = value;
    return;
  }
  YAML::Node sub = section[name.substr(0, dot)];
  WriteKey(sub, name.substr(dot + 1), value);
}

}  // namespace

const std::vector<std::string>& StorageConfigKeys() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const ServerKey& k : StorageKeys()) n.push_back(k.name);
    return n;
  }();
  return names;
}

const std::vector<std::string>& ServerConfigKeys() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const ServerKey& k : Keys()) n.push_back(k.name);
    return n;
  }();
  return names;
}

Result<ServerConfig> ServerConfigFromYaml(const YAML::Node& root, const ServerConfig& base) {
  ServerConfig config = base;
  if (!root || root.IsNull()) return config;
  if (!root.IsMap()) return Status::InvalidArgument("config: the document must be a mapping");
  Result<MapParams> params =
      MapParamsFromYaml(root, {"server", "storage", "georeference", "cluster"}, base.map);
  if (!params.ok()) return params.status();
  config.map = *params;
  if (root["server"] && !root["server"].IsNull()) {  // "server:" alone means defaults
    if (Status s = ReadSection(root["server"], "server", Keys(), config); !s.ok()) return s;
  }
  if (root["storage"] && !root["storage"].IsNull()) {
    if (Status s = ReadSection(root["storage"], "storage", StorageKeys(), config); !s.ok()) {
      return s;
    }
  }
  if (root["georeference"] && !root["georeference"].IsNull()) {
    if (Status s = ReadSection(root["georeference"], "georeference", GeoreferenceKeys(), config);
        !s.ok()) {
      return s;
    }
  }
  if (root["cluster"] && !root["cluster"].IsNull()) {
    if (Status s = ReadSection(root["cluster"], "cluster", ClusterKeys(), config); !s.ok()) {
      return s;
    }
  }
  if (Status s = ValidateServerConfig(config); !s.ok()) return s;
  return config;
}

std::string ServerConfigToYaml(const ServerConfig& config) {
  YAML::Node root = MapParamsToYaml(config.map);
  YAML::Node server(YAML::NodeType::Map);
  for (const ServerKey& k : Keys()) WriteKey(server, k.name, k.write(config));
  root["server"] = server;
  YAML::Node storage(YAML::NodeType::Map);
  for (const ServerKey& k : StorageKeys()) storage[k.name] = k.write(config);
  root["storage"] = storage;
  YAML::Node georeference(YAML::NodeType::Map);
  for (const ServerKey& k : GeoreferenceKeys()) georeference[k.name] = k.write(config);
  root["georeference"] = georeference;
  YAML::Node cluster(YAML::NodeType::Map);
  for (const ServerKey& k : ClusterKeys()) WriteKey(cluster, k.name, k.write(config));
  // A password or token in a NATS URL is never printed.
  cluster["nats"] = RedactUrlSecrets(config.cluster.nats);
  root["cluster"] = cluster;
  YAML::Emitter out;
  out << root;
  return std::string(out.c_str()) + "\n";
}

Status ApplyConfigOverride(ServerConfig& config, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    return Status::InvalidArgument("--set " + assignment + ": expected KEY=VALUE");
  }
  const std::string key = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument("--set " + key + ": " + e.what());
  }
  YAML::Node root(YAML::NodeType::Map);
  const size_t dot = key.find('.');
  const std::string section = dot == std::string::npos ? "" : key.substr(0, dot);
  if (section == "server" || section == "storage" || section == "georeference" ||
      section == "cluster") {
    root[section][key.substr(dot + 1)] = value;
  } else {
    root[key] = value;
  }
  Result<ServerConfig> updated = ServerConfigFromYaml(root, config);
  if (!updated.ok()) return updated.status();
  config = *updated;
  return Status::Ok();
}

namespace {

Status Bad(const std::string& key, const std::string& why) {
  return Status::InvalidArgument("server." + key + ": " + why);
}

// server.foxglove.*: a region the Grid can cover, limits that let a client connect.
Status ValidateFoxglove(const ServerConfig& c) {
  const FoxgloveConfig& f = c.foxglove;
  if (!f.enabled()) return Status::Ok();
  if (Result<HostPort> a = ParseHostPort(f.address); !a.ok()) {
    return Bad("foxglove.address", a.status().message() + " (\"\" turns the port off)");
  }
  const std::vector<double>& r = f.region;
  if (r.size() != 4 ||
      !std::all_of(r.begin(), r.end(), [](double v) { return std::isfinite(v); }) || r[0] >= r[2] ||
      r[1] >= r[3]) {
    return Bad("foxglove.region", "must be [xmin, ymin, xmax, ymax] in metres, finite, min < max");
  }
  const double cells = std::ceil((r[2] - r[0]) / c.map.resolution + 1) *
                       std::ceil((r[3] - r[1]) / c.map.resolution + 1);
  if (cells > static_cast<double>(c.limits.max_region_cells)) {
    return Bad("foxglove.region", "covers about " + std::to_string(static_cast<uint64_t>(cells)) +
                                      " cells, more than server.max_region_cells = " +
                                      std::to_string(c.limits.max_region_cells));
  }
  if (f.max_clients == 0) return Bad("foxglove.max_clients", "must be >= 1");
  if (f.max_queued_bytes < (1u << 20)) return Bad("foxglove.max_queued_bytes", "must be >= 1 MiB");
  return Status::Ok();
}

// server.*: the listeners, threads and logging.
Status ValidateServerKeys(const ServerConfig& c) {
  if (c.listen_address.empty()) return Bad("listen_address", "must not be empty");
  if (!c.metrics_address.empty()) {
    if (Result<HostPort> m = ParseHostPort(c.metrics_address); !m.ok()) {
      return Bad("metrics_address", m.status().message() + " (\"\" turns the endpoint off)");
    }
  }
  static const std::vector<std::string> kLevels = {"trace", "debug",    "info", "warn",
                                                   "error", "critical", "off"};
  if (std::find(kLevels.begin(), kLevels.end(), c.log_level) == kLevels.end()) {
    return Bad("log_level", "'" + c.log_level + "' is not one of trace|debug|info|warn|error|off");
  }
  if (Status s = ValidateFoxglove(c); !s.ok()) return s;
  if (c.worker_threads < 0 || c.worker_threads > 1024) return Bad("worker_threads", "0..1024");
  if (c.query_threads < 0 || c.query_threads > 1024) return Bad("query_threads", "0..1024");
  if (c.worker_nice < 0 || c.worker_nice > 19) return Bad("worker_nice", "0..19");
  for (int cpu : c.worker_cpus) {
    if (cpu < 0 || cpu > 1023) return Bad("worker_cpus", "each a CPU number, 0..1023");
  }
  if (c.malloc_arenas < 0 || c.malloc_arenas > 1024) return Bad("malloc_arenas", "0..1024");
  if (c.scan_bands < 0 || c.scan_bands > 64) return Bad("scan_bands", "0..64");
  if (c.shutdown_timeout_s < 0) return Bad("shutdown_timeout_s", "must be >= 0");
  return Status::Ok();
}

// server.max_*, the limits on what a client may ask.
Status ValidateLimits(const ServerLimits& l, double resolution) {
  if (l.max_points_per_scan == 0) return Bad("max_points_per_scan", "must be > 0");
  if (l.max_correction_scans == 0) return Bad("max_correction_scans", "must be > 0");
  if (l.max_region_cells == 0) return Bad("max_region_cells", "must be > 0");
  if (l.max_region_read_cells < l.max_region_cells) {
    return Bad("max_region_read_cells",
               "must be >= max_region_cells (a stride-1 region reads as "
               "many map cells as it has pixels)");
  }
  if (l.max_region_bytes_in_flight == 0) return Bad("max_region_bytes_in_flight", "must be > 0");
  if (!(l.max_coordinate > 0)) return Bad("max_coordinate", "must be > 0");
  if (l.max_coordinate > kMaxCellIndex * resolution / 2) {
    std::ostringstream why;
    why << "must be below half the engine's range (" << kMaxCellIndex * resolution / 2
        << " m at resolution " << resolution << ")";
    return Bad("max_coordinate", why.str());
  }
  if (!(l.quaternion_tolerance > 0 && l.quaternion_tolerance < 0.5)) {
    return Bad("quaternion_tolerance", "must be in (0, 0.5)");
  }
  if (l.max_inflight_scans_per_stream == 0) {
    return Bad("max_inflight_scans_per_stream", "must be > 0");
  }
  if (l.max_message_bytes < (1u << 20)) return Bad("max_message_bytes", "must be >= 1 MiB");
  if (l.max_message_bytes > (1ull << 31) - 1) return Bad("max_message_bytes", "must be < 2 GiB");
  if (l.max_points_per_scan * 12 + 4096 > l.max_message_bytes) {
    return Bad("max_points_per_scan", std::to_string(l.max_points_per_scan) +
                                          " points (12 bytes each) exceed "
                                          "server.max_message_bytes = " +
                                          std::to_string(l.max_message_bytes));
  }
  if (l.region_chunk_bytes < 4096 || l.region_chunk_bytes > l.max_message_bytes / 2) {
    return Bad("region_chunk_bytes", "must be in [4096, max_message_bytes / 2]");
  }
  if (l.max_import_bytes == 0) return Bad("max_import_bytes", "must be > 0");
  if (l.max_footprint_cells == 0) return Bad("max_footprint_cells", "must be > 0");
  if (l.max_path_check_cells == 0) return Bad("max_path_check_cells", "must be > 0");
  for (const auto& [key, value] :
       {std::pair<const char*, double>{"ingest_idle_timeout_s", l.ingest_idle_timeout_s},
        {"stalled_write_timeout_s", l.stalled_write_timeout_s},
        {"import_idle_timeout_s", l.import_idle_timeout_s},
        {"max_query_seconds", l.max_query_seconds}}) {
    if (!(value >= 0) || value > 86'400) return Bad(key, "must be in [0, 86400] (0 = never)");
  }
  return Status::Ok();
}

Status ValidateStorage(const StorageConfig& st) {
  auto bad_storage = [](const std::string& key, const std::string& why) {
    return Status::InvalidArgument("storage." + key + ": " + why);
  };
  if (st.durability != "sync" && st.durability != "periodic") {
    return bad_storage("durability", "'" + st.durability + "' is not one of sync|periodic");
  }
  if (st.periodic_sync_ms == 0 || st.periodic_sync_ms > 60'000) {
    return bad_storage("periodic_sync_ms", "must be in 1..60000");
  }
  if (!(st.checkpoint_interval_s > 0) || st.checkpoint_interval_s > 86'400) {
    return bad_storage("checkpoint_interval_s", "must be in (0, 86400]");
  }
  if (st.max_memory_mb > 0 && st.data_dir.empty()) {
    return bad_storage("max_memory_mb", "needs storage.data_dir (evicted tiles live in the store)");
  }
  if (st.max_memory_mb > (uint64_t{1} << 30)) {
    return bad_storage("max_memory_mb", "must be at most 2^30 (1 PiB)");
  }
  if (st.dense_tiles_mb > (uint64_t{1} << 30)) {
    return bad_storage("dense_tiles_mb", "must be at most 2^30 (1 PiB)");
  }
  if (st.min_free_space_mb > (uint64_t{1} << 30)) {
    return bad_storage("min_free_space_mb", "must be at most 2^30 (1 PiB)");
  }
  if (st.retention_mb > (uint64_t{1} << 30)) {
    return bad_storage("retention_mb", "must be at most 2^30 (1 PiB)");
  }
  if (!(st.retention_s >= 0) || st.retention_s > 1e9) {
    return bad_storage("retention_s", "must be in [0, 1e9] seconds of map time");
  }
  return Status::Ok();
}

Status ValidateGeoreference(const GeoreferenceConfig& geo) {
  for (double v : geo.origin) {
    if (!std::isfinite(v)) return Status::InvalidArgument("georeference.origin: must be finite");
  }
  if (geo.crs.empty() && geo.origin != std::array<double, 3>{0, 0, 0}) {
    return Status::InvalidArgument(
        "georeference.origin: needs georeference.crs (the system the origin is given in)");
  }
  return Status::Ok();
}

}  // namespace

Status ValidateServerConfig(const ServerConfig& c) {
  if (Status s = c.map.Validate(); !s.ok()) return s;
  if (Status s = ValidateServerKeys(c); !s.ok()) return s;
  if (Status s = ValidateLimits(c.limits, c.map.resolution); !s.ok()) return s;
  if (Status s = ValidateStorage(c.storage); !s.ok()) return s;
  return ValidateGeoreference(c.georeference);
}

Status ValidateCluster(const ServerConfig& c) {
  if (!c.cluster.enabled()) return Status::Ok();
  auto bad_cluster = [](const std::string& key, const std::string& why) {
    return Status::InvalidArgument("cluster." + key + ": " + why);
  };
  if (c.cluster.node.empty()) return bad_cluster("node", "must name this shard (unique)");
  if (c.cluster.node.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                       "0123456789-_") != std::string::npos) {
    return bad_cluster("node", "'" + c.cluster.node + "' may hold only letters, digits, - and _");
  }
  if (c.cluster.partition_tiles < 1 || c.cluster.partition_tiles > 1024) {
    return bad_cluster("partition_tiles", "must be in [1, 1024]");
  }
  if (c.cluster.replicas < 1 || c.cluster.replicas > 5) {
    return bad_cluster("replicas", "must be in [1, 5] (JetStream's limit)");
  }
  if (!(c.cluster.lease_s >= 0.5 && c.cluster.lease_s <= 60)) {
    return bad_cluster("lease_s", "must be in [0.5, 60] seconds");
  }
  if (!(c.cluster.dedupe_window_s >= 1 && c.cluster.dedupe_window_s <= 86400 * 7)) {
    return bad_cluster("dedupe_window_s", "must be in [1, 604800] seconds");
  }
  if (!(c.cluster.startup_wait_s >= 0 && c.cluster.startup_wait_s <= 86400)) {
    return bad_cluster("startup_wait_s", "must be in [0, 86400] seconds");
  }
  if (c.cluster.key_file.empty() && !c.cluster.insecure) {
    return bad_cluster("key_file",
                       "a shard needs cluster.key_file (a secret shared by the shards, at least "
                       "32 bytes) or cluster.insecure: true (then anyone who can publish to "
                       "NATS can change the map)");
  }
  // A signed log entry is refused when stored more than 60 s (+ 30 s of clock skew) after its
  // signature (cluster_log.h, kMaxEntryDelay); within that, JetStream's de-duplication of its
  // signed message id must stop a copy of it.
  if (!c.cluster.key_file.empty() && c.cluster.dedupe_window_s < 90) {
    return bad_cluster("dedupe_window_s",
                       "must be at least 90 seconds with cluster.key_file (a copy of an entry "
                       "published again within 90 s is stopped by it)");
  }
  if (c.cluster.nats_tls.cert_file.empty() != c.cluster.nats_tls.key_file.empty()) {
    return bad_cluster(
        c.cluster.nats_tls.cert_file.empty() ? "nats_tls.cert_file" : "nats_tls.key_file",
        "nats_tls.cert_file and nats_tls.key_file are set together");
  }
  if (c.cluster.region_partitions > 4096) {
    return bad_cluster("region_partitions", "must be in [0, 4096] partitions");
  }
  if (c.cluster.region_partitions > 0 && c.cluster.trim_lag_entries > 0) {
    return bad_cluster("region_partitions",
                       "streams per region are not trimmed yet: set cluster.trim_lag_entries "
                       "to 0 with cluster.region_partitions > 0");
  }
  if (c.cluster.trim_lag_entries > 0 && c.cluster.checkpoint_scans == 0) {
    return bad_cluster("trim_lag_entries",
                       "trimming the log needs checkpoints: set cluster.checkpoint_scans > 0");
  }
  if (!c.storage.data_dir.empty()) {
    return bad_cluster("nats",
                       "a shard keeps its partitions in memory and rebuilds them from "
                       "the cluster's log; storage.data_dir must be empty");
  }
  return Status::Ok();
}

Status ValidateSecurity(const ServerConfig& c) {
  auto bad = [](const std::string& key, const std::string& why) {
    return Status::InvalidArgument("server." + key + ": " + why);
  };
  if (c.tls.key_file.empty() != c.tls.cert_file.empty()) {
    return bad(c.tls.cert_file.empty() ? "tls.cert_file" : "tls.key_file",
               "tls.cert_file and tls.key_file are set together");
  }
  if (!c.tls.client_ca_file.empty() && !c.tls.enabled()) {
    return bad("tls.client_ca_file", "needs server.tls.cert_file (client certificates need TLS)");
  }
  if (!c.insecure) {
    for (const auto& [key, address] :
         {std::pair<const char*, const std::string&>{"listen_address", c.listen_address},
          {"metrics_address", c.metrics_address},
          {"foxglove.address", c.foxglove.address}}) {
      if (address.empty() || IsLoopbackAddress(address)) continue;
      if (!c.tls.enabled() || !c.auth.enabled()) {
        return bad(key, "'" + address +
                            "' is not a loopback address: serving it needs server.tls.cert_file "
                            "and server.auth.tokens_file (or server.insecure: true)");
      }
    }
  }
  return Status::Ok();
}

std::string RedactUrlSecrets(const std::string& urls) {
  std::string out;
  size_t from = 0;
  while (from <= urls.size()) {
    size_t end = urls.find(',', from);
    if (end == std::string::npos) end = urls.size();
    std::string url = urls.substr(from, end - from);
    const size_t scheme = url.find("://");
    const size_t host = scheme == std::string::npos ? std::string::npos : scheme + 3;
    const size_t at = host == std::string::npos ? std::string::npos : url.find('@', host);
    if (at != std::string::npos) {
      const size_t colon = url.find(':', host);
      const size_t secret = colon != std::string::npos && colon < at ? colon + 1 : host;
      url.replace(secret, at - secret, "***");
    }
    out += url;
    if (end == urls.size()) break;
    out += ',';
    from = end + 1;
  }
  return out;
}

bool IsLoopbackAddress(const std::string& address) {
  if (address.rfind("unix:", 0) == 0 || address.rfind("unix-abstract:", 0) == 0) return true;
  Result<HostPort> hp = ParseHostPort(address);
  if (!hp.ok()) return false;
  const std::string& h = hp->host;
  return h == "localhost" || h == "::1" || h.rfind("127.", 0) == 0;
}

uint32_t QueriesPerToken(const ServerConfig& c) {
  if (c.auth.max_queries_per_token > 0) return c.auth.max_queries_per_token;
  return std::max<uint32_t>(1, c.limits.max_concurrent_queries / 4);
}

uint32_t IngestStreamsPerToken(const ServerConfig& c) {
  if (c.auth.max_ingest_streams_per_token > 0) return c.auth.max_ingest_streams_per_token;
  return std::max<uint32_t>(1, c.limits.max_ingest_streams / 4);
}

uint32_t WatchersPerToken(const ServerConfig& c) {
  if (c.auth.max_watchers_per_token > 0) return c.auth.max_watchers_per_token;
  return std::max<uint32_t>(1, c.limits.max_watchers / 4);
}

uint32_t EventStreamsPerToken(const ServerConfig& c) {
  if (c.auth.max_event_streams_per_token > 0) return c.auth.max_event_streams_per_token;
  return std::max<uint32_t>(1, kMaxEventStreams / 4);
}

}  // namespace bgkmap
