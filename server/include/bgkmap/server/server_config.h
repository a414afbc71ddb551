// Configuration of bgkmapd: the engine parameters (top-level YAML keys, as for the offline tools)
// plus a `server:` section. Command-line flags override the file; --print-config shows the result.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace YAML {
class Node;
}

namespace bgkmap {

// Limits that protect the server; every violation is reported with the key name and its value.
struct ServerLimits {
  uint64_t max_points_per_scan = 2'000'000;  // max_points_per_scan
  // max_region_cells: output pixels per region query (map cells / stride^2), so a coarse
  // query covers a larger area; the raster the server holds is this size.
  uint64_t max_region_cells = 4'000'000;
  // max_region_read_cells: map cells a region query reads (pixels x stride^2): bounds its time
  // and the tiles it loads from the store.
  uint64_t max_region_read_cells = 64'000'000;
  uint64_t max_query_points = 100'000;  // max_query_points: points per point query
  uint64_t max_path_poses = 10'000;     // max_path_poses: poses per path check
  // max_correction_scans: entries per CorrectPoses request (at most the robot's retained scans
  // as well); bounds the request's bytes before it is parsed.
  uint64_t max_correction_scans = 100'000;
  uint64_t max_footprint_cells = 100'000;  // max_footprint_cells: cells under one footprint
  // max_path_check_cells: footprint bounding-box cells summed over a path check's placements
  // (its poses and the samples between them: the work a CheckPath costs), checked before any
  // cell is visited.
  uint64_t max_path_check_cells = 20'000'000;
  double max_coordinate = 1e6;                       // max_coordinate: |x|, |y|, |z| bound, metres
  double quaternion_tolerance = 1e-3;                // quaternion_tolerance: allowed | |q| - 1 |
  uint32_t max_inflight_scans_per_stream = 8;        // max_inflight_scans_per_stream: read-ahead
  uint32_t max_inflight_unary_scans = 64;            // max_inflight_unary_scans: IngestScan calls
  uint32_t max_ingest_streams = 256;                 // max_ingest_streams
  uint32_t max_robots = 4096;                        // max_robots: distinct robot ids
  uint32_t max_watchers = 64;                        // max_watchers
  uint64_t max_watch_tiles = 65'536;                 // max_watch_tiles: tiles per watched region
  uint32_t max_concurrent_queries = 64;              // max_concurrent_queries
  uint64_t max_region_bytes_in_flight = 1ull << 30;  // max_region_bytes_in_flight: rasters held
  uint64_t max_message_bytes = 64ull << 20;          // max_message_bytes: largest gRPC message
  uint64_t region_chunk_bytes = 1ull << 20;          // region_chunk_bytes: target chunk size
  uint64_t max_import_bytes = 1ull << 30;  // max_import_bytes: largest archive ImportMap takes
  // max_sequence_jump: a scan whose sequence number exceeds the robot's last one (0 for a new
  // robot) by more than this is refused (OUT_OF_RANGE), so one bad scan cannot make every later
  // scan of the robot a duplicate. 0 = no limit.
  uint64_t max_sequence_jump = uint64_t{1} << 32;
  // Idle and stalled peers give their slot back (0 = never):
  //   ingest_idle_timeout_s: an Ingest stream with nothing in flight that sends no scan for this
  //     long is ended (DEADLINE_EXCEEDED);
  //   stalled_write_timeout_s: a stream whose client does not take a message (an ack, a region
  //     chunk, a tile update, an export chunk) for this long is cancelled;
  //   import_idle_timeout_s: an ImportMap upload that sends no chunk for this long is ended;
  //   max_query_seconds: a unary query (points, path, info) still running after this long stops
  //     and answers DEADLINE_EXCEEDED (a client deadline, if shorter, is honoured too).
  double ingest_idle_timeout_s = 300;
  double stalled_write_timeout_s = 60;
  double import_idle_timeout_s = 60;
  double max_query_seconds = 30;
};

// The `storage:` section: where and how the map is persisted (docs/storage.md).
struct StorageConfig {
  std::string data_dir;               // data_dir: the store's directory ("" = in memory only)
  std::string durability = "sync";    // durability: sync|periodic (when an ack is durable)
  uint32_t periodic_sync_ms = 100;    // periodic_sync_ms: power-loss window of "periodic"
  double checkpoint_interval_s = 30;  // checkpoint_interval_s: tiles written, log truncated
  // max_memory_mb: bound on the tiles kept in memory (0 = keep every tile). Clean tiles not
  // used recently are dropped (the store has them) and loaded again on demand; changed tiles
  // are checkpointed first. Needs data_dir.
  uint64_t max_memory_mb = 0;
  // dense_tiles_mb: budget of the tiles kept dense (0 = every tile dense). A tile's 64x64 cells
  // take 128 KiB dense whatever number are known; beyond this budget the tiles used least
  // recently are packed to their known cells (bit for bit, about 32 bytes per stored cell), and
  // made dense again when an operation next touches them: less memory for a unpacking cost on
  // the next scan or query there. With max_memory_mb, both count the real bytes.
  uint64_t dense_tiles_mb = 16;
  // verify_on_start: read and check every stored tile in the background after start, so that
  // damage is reported before a query meets it (tiles are otherwise read only on demand).
  bool verify_on_start = true;
  // min_free_space_mb: free space kept on the data directory's file system. A write (scan, clear,
  // checkpoint, import, robot retirement) that would leave less is refused with UNAVAILABLE
  // before RocksDB sees it, reads go on, and writes resume once there is room; a server started
  // with less free opens its store read-only. It covers RocksDB's own flushes and compactions
  // and the restart after a refusal (docs/storage.md, "Free-space reserve"). 0 = no reserve.
  uint64_t min_free_space_mb = 64;
  // retention_mb: bound on the raw scans and log records kept below the last checkpoint so that
  // a robot's poses can be corrected later (CorrectPoses, RemoveScans; docs/semantics.md,
  // "Pose corrections"); older ones are dropped at checkpoints. 0 = keep none (no corrections).
  // Needs data_dir.
  uint64_t retention_mb = 1024;
  // retention_s: bound on their age in map time (scan stamps); 0 = no bound by age.
  double retention_s = 0;
};

// The `georeference:` section: where the robots' local map frame sits in a coordinate reference
// system, so GeoTIFFs and GIS tools place the map (docs/configuration.md).
struct GeoreferenceConfig {
  std::string crs;                           // crs: "EPSG:<code>", WKT or PROJ ("" = local frame)
  std::array<double, 3> origin = {0, 0, 0};  // origin: [easting, northing, height] of map (0,0,0)
};

// The `cluster:` section: a shard of a map cluster on NATS JetStream (docs/scale-out.md). Off
// while `nats` is empty.
struct ClusterConfig {
  std::string nats;               // nats: the NATS servers, comma-separated ("nats://h:4222,...")
  std::string node;               // node: this shard's name, unique in the cluster
  uint32_t partition_tiles = 8;   // partition_tiles: a partition is this many tiles square
  uint32_t replicas = 1;          // replicas: JetStream copies of the log and the KV buckets
  double lease_s = 3.0;           // lease_s: a shard silent this long loses its partitions
  double dedupe_window_s = 3600;  // dedupe_window_s: a retried scan inside it is stored once
  // startup_wait_s: how long a starting shard waits for NATS JetStream to answer (a clustered
  // JetStream answers once it has elected its leaders), saying so, before it gives up.
  double startup_wait_s = 120;
  // checkpoint_scans: a partition's owner checkpoints it after this many scans integrated there
  // (0: never; a takeover then reads the log from its start).
  uint32_t checkpoint_scans = 500;
  // trim_lag_entries: 0 keeps the whole log. Else a partition whose newest checkpoint lags the
  // log by this many entries is checkpointed even if idle, and the log is trimmed below the
  // oldest of the partitions' newest checkpoints (docs/scale-out.md, "Trimming the log").
  uint32_t trim_lag_entries = 0;
  // region_partitions: 0 keeps every scan's payload in the log, which every shard reads. Else
  // the site is cut into regions of this many partitions square, each owned by one shard, and a
  // scan's payload is stored in a stream per region it touches: a shard reads every entry's
  // headers but only its regions' payloads (docs/scale-out.md, "Streams per region"). Every
  // shard must run the same value (the shards compare it at start).
  uint32_t region_partitions = 0;
  // key_file: a file holding the cluster's secret (at least 32 bytes, readable by its owner
  // only). Every log entry, tile-fetch reply and membership record carries an HMAC-SHA256 with
  // it, and a shard believes nothing that fails it (docs/scale-out.md, "Trust"). Only the path
  // is configuration; the secret is never logged or printed.
  std::string key_file;
  // insecure: true lets a shard run without key_file (then anyone who can publish to NATS can
  // change the map).
  bool insecure = false;
  // nats_credentials: a NATS user credentials file (.creds: the user's JWT and nkey seed), how
  // the shard authenticates to NATS; "" = none (or a user in the URL).
  std::string nats_credentials;
  // nats_tls: TLS to the NATS servers. ca_file: the CAs the servers' certificates are checked
  // against (set = TLS); cert_file and key_file (together): the shard's client certificate, for
  // servers that verify clients.
  struct NatsTls {
    std::string ca_file, cert_file, key_file;
    bool enabled() const { return !ca_file.empty() || !cert_file.empty(); }
  } nats_tls;
  bool enabled() const { return !nats.empty(); }
};

// `server.tls`: TLS on the gRPC port and the HTTP (metrics) port (docs/server.md, Security).
struct TlsConfig {
  std::string cert_file;  // tls.cert_file: the server's certificate chain (PEM); "" = plaintext
  std::string key_file;   // tls.key_file: its private key (PEM)
  std::string client_ca_file;  // tls.client_ca_file: CAs of client certificates; set = mTLS
  bool enabled() const { return !cert_file.empty(); }
};

// Open GET /events streams of the web map at once (docs/webmap.md), all tokens together.
inline constexpr uint32_t kMaxEventStreams = 16;

// `server.auth`: bearer tokens and their roles, and what one token may hold at a time.
struct AuthConfig {
  // auth.tokens_file: YAML `tokens: [{name, sha256, role, robots}]`; "" = no authentication.
  // Re-read on SIGHUP.
  std::string tokens_file;
  // auth.max_queries_per_token / auth.max_ingest_streams_per_token: concurrent queries and open
  // Ingest streams of one token (a token's own `max_queries` / `max_ingest_streams` in the
  // tokens file win). 0 = a quarter of server.max_concurrent_queries / max_ingest_streams.
  uint32_t max_queries_per_token = 0;
  uint32_t max_ingest_streams_per_token = 0;
  // auth.max_watchers_per_token / auth.max_event_streams_per_token: open Watch streams and open
  // GET /events streams of one token (a token's own `max_watchers` / `max_event_streams` win).
  // 0 = a quarter of server.max_watchers / of the web map's kMaxEventStreams.
  uint32_t max_watchers_per_token = 0;
  uint32_t max_event_streams_per_token = 0;
  bool enabled() const { return !tokens_file.empty(); }
};

// `server.foxglove`: the Foxglove WebSocket port (docs/foxglove.md). Off while `address` is "".
struct FoxgloveConfig {
  std::string address;  // foxglove.address: host:port (`--foxglove`; port 0 = any free port)
  // foxglove.region: [xmin, ymin, xmax, ymax] in metres, the map sent as /map (foxglove.Grid);
  // at most server.max_region_cells cells.
  std::vector<double> region = {-50, -50, 50, 50};
  uint32_t max_clients = 16;              // foxglove.max_clients: connected at once
  uint64_t max_queued_bytes = 64u << 20;  // foxglove.max_queued_bytes: unsent, per client
  uint32_t max_scan_points = 100'000;     // foxglove.max_scan_points: kept of a robot's scan
  bool enabled() const { return !address.empty(); }
};

struct ServerConfig {
  MapParams map;
  std::string listen_address = "127.0.0.1:50051";  // listen_address (host:port; port 0 = any)
  int worker_threads = 0;  // worker_threads: scan preparation and integration (0 = all cores)
  int query_threads = 0;   // query_threads: queries and watch updates (0 = all cores)
  // worker_nice: the worker threads' nice increment (0..19): a planner waits on its query, while a
  // scan's integration can wait a few milliseconds, so on busy cores queries run first.
  int worker_nice = 10;
  // worker_cpus: pins worker i to CPU worker_cpus[i % size] ([] = not pinned, the default). For
  // a robot computer that keeps cores for the mapping server, and for schedulers that wake a
  // thread on its waker's busy core (docs/server.md "Server keys"). Every CPU must be one the
  // process may run on.
  std::vector<int> worker_cpus;
  // malloc_arenas: glibc's heap arenas at most (0 = glibc's own limit, 8 per core). Threads that
  // take in scans leave freed memory resident in arenas of their own; two arenas cut what the
  // process holds above its tiles (docs/benchmarks.md, "Memory per known cell"). The
  // environment's MALLOC_ARENA_MAX, when set, wins.
  int malloc_arenas = 2;
  // scan_bands: a dense scan's integration is cut into at most this many bands of whole tiles,
  // run on idle workers beside each other; the map is the same bit for bit (0 = one band per
  // worker thread, 1 = every scan on one thread; docs/benchmarks.md "A scan in bands").
  int scan_bands = 1;
  std::string log_level = "info";    // log_level: trace|debug|info|warn|error|off
  double shutdown_timeout_s = 30.0;  // shutdown_timeout_s: grace for in-flight calls
  // metrics_address: host:port of the HTTP endpoint (`--http`, or `--metrics`): GET /metrics for
  // Prometheus, the live web map with its event stream, /login; "" = off, port 0 = any free port
  // (logged as event=metrics_listening). The key keeps its first name, which the tests and
  // operators' configs use.
  std::string metrics_address;
  FoxgloveConfig foxglove;
  TlsConfig tls;
  AuthConfig auth;
  // insecure: allow a non-loopback listen or metrics address without TLS and tokens.
  bool insecure = false;
  ServerLimits limits;
  StorageConfig storage;
  GeoreferenceConfig georeference;
  ClusterConfig cluster;
};

// The keys of the `server:` section, in documentation order.
const std::vector<std::string>& ServerConfigKeys();

// The keys of the `storage:` section, in documentation order.
const std::vector<std::string>& StorageConfigKeys();

// Reads a whole config document: engine keys at the top level, server keys under `server:`,
// storage keys under `storage:`.
// Starts from `base`; unknown keys and bad values fail with a message naming the key.
Result<ServerConfig> ServerConfigFromYaml(const YAML::Node& root,
                                          const ServerConfig& base = ServerConfig{});

// The effective configuration as a YAML document (what --print-config prints).
std::string ServerConfigToYaml(const ServerConfig& config);

// Applies one "key=value" override: an engine key, "server.<key>" or "storage.<key>".
Status ApplyConfigOverride(ServerConfig& config, const std::string& assignment);

// Checks cross-field rules (the engine parameters and the limits).
Status ValidateServerConfig(const ServerConfig& config);

// Checks the security keys together, once every override is applied (MapServer::Start): TLS
// cert and key come as a pair, and a non-loopback address needs TLS and tokens unless
// server.insecure. Files are read by the server at start, not here.
Status ValidateSecurity(const ServerConfig& config);

// Checks the `cluster:` keys together, once every override is applied (MapServer::Start).
Status ValidateCluster(const ServerConfig& config);

// True for a loopback address ("127.x.x.x:p", "localhost:p", "[::1]:p") or a unix socket.
bool IsLoopbackAddress(const std::string& address);

// `urls` (comma-separated, as cluster.nats) with the secret of any user info hidden:
// "nats://bob:pw@h:4222" -> "nats://bob:***@h:4222", "nats://token@h" -> "nats://***@h". What
// logs and --print-config show.
std::string RedactUrlSecrets(const std::string& urls);

// The per-token limits in effect (0 in the config: a quarter of the global limit, at least 1).
uint32_t QueriesPerToken(const ServerConfig& config);
uint32_t IngestStreamsPerToken(const ServerConfig& config);
uint32_t WatchersPerToken(const ServerConfig& config);
uint32_t EventStreamsPerToken(const ServerConfig& config);

}  // namespace bgkmap
