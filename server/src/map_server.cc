#include "bgkmap/server/map_server.h"

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <condition_variable>
#include <future>
#include <mutex>
#include <optional>
#include <string_view>
#include <thread>

#include "auth/tls_files.h"
#include "auth/token_table.h"
#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/server/host_port.h"
#include "bgkmap/v1/map_service.pb.h"
#include "cluster/cluster_node.h"
#include "durability/durability.h"
#include "durability/memory_durability.h"
#include "durability/store_durability.h"
#include "foxglove/foxglove_server.h"
#include "foxglove/messages.h"
#include "http/http_server.h"
#include "http/https_context.h"
#include "http/metrics.h"
#include "http/web_routes.h"
#include "rpc/malformed_request.h"
#include "rpc/map_service.h"
#include "rpc/request_checks.h"
#include "rpc/service_context.h"
#include "serving/latest_scans.h"
#include "serving/map_maintenance.h"
#include "serving/served_map.h"
#include "worker_threads.h"

namespace bgkmap {
namespace {

// gRPC tears its library down when the last user goes away, and that teardown can block for
// seconds (an executor thread finishing a 10 s poll). A process-lifetime reference avoids it;
// the process exit releases everything anyway.
void KeepGrpcInitialized() {
  static std::once_flag once;
  std::call_once(once, [] { grpc_init(); });
}

// Server reflection answers from protobuf's generated pool, which holds only the .proto files
// linked in. map_service.pb.cc defines no messages, so nothing would pull it out of the static
// library: name its descriptor table to keep it.
void KeepServiceDescriptorLinked() {
  static const void* volatile keep = &::descriptor_table_bgkmap_2fv1_2fmap_5fservice_2eproto;
  (void)keep;
}

// How often idle and stalled streams are looked for: a quarter of the shortest timeout, within
// [20 ms, 1 s].
std::chrono::milliseconds WatchdogPeriod(const ServerLimits& l) {
  double shortest = 4.0;
  for (double t : {l.ingest_idle_timeout_s, l.stalled_write_timeout_s, l.import_idle_timeout_s}) {
    if (t > 0) shortest = std::min(shortest, t);
  }
  return std::chrono::milliseconds(
      std::clamp(static_cast<int64_t>(shortest * 1000 / 4), int64_t{20}, int64_t{1000}));
}

// The gRPC port's credentials: TLS with server.tls (client certificates required and verified
// with client_ca_file), plaintext otherwise.
std::shared_ptr<grpc::ServerCredentials> GrpcCredentials(const std::optional<TlsMaterial>& tls) {
  if (!tls.has_value()) return grpc::InsecureServerCredentials();
  grpc::SslServerCredentialsOptions options(
      tls->client_ca_pem.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                 : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  options.pem_root_certs = tls->client_ca_pem;
  options.pem_key_cert_pairs.push_back({tls->private_key_pem, tls->cert_chain_pem});
  return grpc::SslServerCredentials(options);
}

// The host of "host:port" as a URL writes it ("[::1]" for IPv6).
std::string HostOf(const std::string& address) {
  Result<HostPort> hp = ParseHostPort(address);
  if (!hp.ok()) return address;
  return hp->host.find(':') != std::string::npos ? "[" + hp->host + "]" : hp->host;
}

size_t ThreadCount(int configured) {
  if (configured > 0) return static_cast<size_t>(configured);
  return std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace

// The server's parts. Member order is construction order: each part uses only those above it,
// and the parts are destroyed in reverse. The map behind the port is one of two: a served map
// (with its durability and maintenance) or a cluster node.
struct MapServer::Impl {
  Impl(const ServerConfig& cfg, std::unique_ptr<TokenTable> token_table)
      : config(cfg),
        tokens(std::move(token_table)),
        ingest_pool(ThreadCount(cfg.worker_threads)),
        query_pool(ThreadCount(cfg.query_threads)) {}

  // A single server's map on `durable` (what it recovered is in `recovered`).
  void OpenServedMap(std::unique_ptr<TerrainMap> recovered, std::unique_ptr<Durability> durable) {
    durability = std::move(durable);
    served = std::make_unique<ServedMap>(std::move(recovered), *durability, ingest_pool,
                                         ServedMapOptionsFor(config));
    maintenance = std::make_unique<MapMaintenance>(*served, *durability, config.storage);
    map = served.get();
  }

  // A shard of a cluster; reads that ask the log run on the query pool.
  Status JoinCluster() {
    YAML::Emitter params_yaml;
    params_yaml << MapParamsToYaml(config.map);
    // Shards must agree on who owns what: the regions are compared with the map's parameters
    // (only when set, so a cluster started before they existed compares as it did).
    std::string compared = params_yaml.c_str();
    if (config.cluster.region_partitions > 0) {
      compared +=
          "\n# cluster.region_partitions: " + std::to_string(config.cluster.region_partitions) +
          "\n";
    }
    auto prepare = [params = config.map, limits = config.limits](
                       const v1::Scan& scan, const Pose* pose, PreparedScan* out) {
      const grpc::Status s = PrepareScanMessage(scan, params, limits, out, nullptr, pose);
      return s.ok() ? Status::Ok() : Status::InvalidArgument(s.error_message());
    };
    Result<std::unique_ptr<cluster::ClusterNode>> joined = cluster::ClusterNode::Start(
        config.cluster, config.map, compared, prepare,
        Georeference{config.georeference.crs, config.georeference.origin},
        [this](std::function<void()> task) { boost::asio::post(query_pool, std::move(task)); },
        RobotSequenceRule{config.limits.max_robots, config.limits.max_sequence_jump});
    if (!joined.ok()) return joined.status();
    cluster = std::move(joined).value();
    // A shard's watchers learn of changes anywhere in the cluster from the log.
    cluster->FollowChanges([this](uint64_t, const CellBox& cells) {
      const GridGeometry& g = cluster->layout().geometry();
      hub.PublishBox(g.TileOf(cells.min), g.TileOf(cells.max));
    });
    map = cluster.get();
    return Status::Ok();
  }

  // Serves GET /metrics and the web map (server.metrics_address).
  Status ListenHttp(const std::optional<TlsMaterial>& tls);
  // Serves the Foxglove WebSocket protocol (server.foxglove.address).
  Status ListenFoxglove(const std::optional<TlsMaterial>& tls);
  // Serves gRPC (server.listen_address).
  Status ListenGrpc(const std::optional<TlsMaterial>& tls);

  // The RPC service over the map.
  void Serve() {
    ctx = std::make_unique<ServiceContext>(config, *map, hub, ingest_pool, query_pool);
    ctx->latest_scans = latest_scans.get();
    service = std::make_unique<MapService>(*ctx, tokens.get());
  }

  ServedMapOptions ServedMapOptionsFor(const ServerConfig& cfg) {
    ServedMapOptions o;
    o.max_robots = cfg.limits.max_robots;
    o.max_sequence_jump = cfg.limits.max_sequence_jump;
    o.tile_memory_limit_bytes = TileMemoryLimit(cfg.storage);
    o.dense_tile_limit_bytes = cfg.storage.dense_tiles_mb << 20;
    o.on_over_memory = [this] { maintenance->RequestEviction(); };
    o.on_tiles_changed = [this](const std::vector<TileKey>& changed) { hub.Publish(changed); };
    o.worker_threads = ThreadCount(cfg.worker_threads);
    o.scan_bands = cfg.scan_bands > 0 ? cfg.scan_bands : static_cast<int>(o.worker_threads);
    return o;
  }

  ServerConfig config;
  std::unique_ptr<TokenTable> tokens;      // null: no authentication
  std::unique_ptr<Durability> durability;  // outlives the workers that journal into it
  WatchHub hub;
  // Each robot's latest scan for the Foxglove port (null when it is off); the ingest workers
  // record into it.
  std::unique_ptr<LatestScans> latest_scans;
  boost::asio::thread_pool ingest_pool;
  boost::asio::thread_pool query_pool;
  std::unique_ptr<ServedMap> served;              // a single server's map (else null)
  std::unique_ptr<MapMaintenance> maintenance;    // with `served`
  std::unique_ptr<cluster::ClusterNode> cluster;  // a cluster node (else null)
  MapPort* map = nullptr;                         // the one of the two
  std::unique_ptr<ServiceContext> ctx;
  std::unique_ptr<MapService> service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;

  std::mutex shutdown_mu;
  bool stopped = false;

  // The web map's routes on the same address; null when off.
  std::unique_ptr<WebRoutes> web;
  // The HTTP endpoint (server.metrics_address): /metrics, the web map, its events, /login; null
  // when off. Last: it reads everything above.
  std::unique_ptr<HttpServer> http;
  int http_port = 0;
  // The Foxglove port (server.foxglove.address); null when off.
  std::unique_ptr<foxglove::FoxgloveServer> foxglove;
  int foxglove_port = 0;
};

MapServer::MapServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

MapServer::~MapServer() { Shutdown(); }

namespace {

// The security files first: a bad one fails the start before the store is opened.
Status LoadSecurity(const ServerConfig& config, std::optional<TlsMaterial>* tls,
                    std::unique_ptr<TokenTable>* tokens) {
  if (config.tls.enabled()) {
    Result<TlsMaterial> loaded = LoadTlsMaterial(config.tls);
    if (!loaded.ok()) return loaded.status();
    *tls = std::move(loaded).value();
  }
  if (config.auth.enabled()) {
    Result<std::unique_ptr<TokenTable>> loaded = TokenTable::Load(
        config.auth.tokens_file, {QueriesPerToken(config), IngestStreamsPerToken(config),
                                  WatchersPerToken(config), EventStreamsPerToken(config)});
    if (!loaded.ok()) {
      return Status::InvalidArgument("server.auth.tokens_file: " + loaded.status().message());
    }
    *tokens = std::move(loaded).value();
  }
  return Status::Ok();
}

// The store with --data-dir (recovered into `map`), memory otherwise.
Result<std::unique_ptr<Durability>> OpenDurability(const ServerConfig& config, TerrainMap& map) {
  const Georeference georeference{config.georeference.crs, config.georeference.origin};
  if (config.storage.data_dir.empty()) {
    return std::unique_ptr<Durability>(std::make_unique<MemoryDurability>(georeference));
  }
  Result<std::unique_ptr<StoreDurability>> opened =
      StoreDurability::Open(config.storage, config.map, georeference, map);
  if (!opened.ok()) return opened.status();
  const StoreDurability& d = **opened;
  const storage::RecoveryReport& r = d.recovery();
  spdlog::info(
      "event=recovered data_dir={} durability={} checkpoint_version={} map_version={} "
      "scans_replayed={} clears_replayed={} tiles={} corrupt_records={} corrupt_tiles={} "
      "seconds={:.3f}",
      d.directory(), d.durability_name(), r.checkpoint_version, r.map_version, r.scans_replayed,
      r.clears_replayed, map.tile_count(), r.corrupt_records.size(), d.CorruptTiles().size(),
      r.seconds);
  return std::unique_ptr<Durability>(std::move(opened).value());
}

}  // namespace

// Binds server.metrics_address before any thread serves, so that a bad address fails the start
// cleanly: GET /metrics and the web map, over TLS with `tls`, behind any token with tokens.
Status MapServer::Impl::ListenHttp(const std::optional<TlsMaterial>& tls) {
  web = std::make_unique<WebRoutes>(*map, hub, query_pool, ctx->queries, config.limits,
                                    WebRoutesOptions{});
  HttpServer::Options http_options;
  http_options.routes = [routes = web.get()](const HttpRequest& request, PrincipalRef who,
                                             std::shared_ptr<HttpExchange> exchange) {
    routes->Handle(request, std::move(who), std::move(exchange));
  };
  if (tls.has_value()) {
    Result<std::shared_ptr<boost::asio::ssl::context>> https = MakeHttpsContext(*tls);
    if (!https.ok()) return https.status();
    http_options.tls = std::move(https).value();
  }
  if (const TokenTable* t = tokens.get()) {
    // Any role's token, for /metrics and the web map alike: what they show (counts, the map's
    // cells) is no secret from a client of the map. /events needs the watch right (WebRoutes).
    http_options.authorize = [t](std::string_view authorization) {
      std::string why;
      return t->Authenticate(authorization, &why);
    };
  }
  // A shard's counts are the cluster's as of its last ReadVersion, which asks the partitions'
  // owners: a scrape starts the next one in the background (one at a time) and shows the
  // previous one's, so /metrics never waits on another shard. A single server's is immediate.
  auto render = [this, refreshing = std::make_shared<std::atomic<bool>>(false)] {
    if (!refreshing->exchange(true)) {
      map->ReadVersion([refreshing](uint64_t) { refreshing->store(false); });
    }
    const ServiceCounts service{ctx->sessions.count(SessionRegistry::Kind::kIngest),
                                ctx->sessions.count(SessionRegistry::Kind::kWatch),
                                &ctx->latencies};
    return FormatMetrics(CollectMetrics(*map, service, config.storage.max_memory_mb << 20));
  };
  Result<std::unique_ptr<HttpServer>> listening =
      HttpServer::Listen(config.metrics_address, render, http_options);
  if (!listening.ok()) {
    return Status::FailedPrecondition("server.metrics_address: " + listening.status().message());
  }
  http = std::move(listening).value();
  http_port = http->port();
  return Status::Ok();
}

// Binds server.foxglove.address: the map around the configured region, the robots' poses and
// last scans, over TLS with `tls`, behind a token that may watch with tokens.
Status MapServer::Impl::ListenFoxglove(const std::optional<TlsMaterial>& tls) {
  foxglove::Options options;
  const std::vector<double>& r = config.foxglove.region;
  options.region = foxglove::RegionCells(map->geometry(), r[0], r[1], r[2], r[3]);
  options.layers = {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability,
                    Layer::kTraversabilityVariance, Layer::kState};
  options.max_clients = config.foxglove.max_clients;
  options.max_queued_bytes = config.foxglove.max_queued_bytes;
  options.tokens = tokens.get();
  if (tls.has_value()) {
    Result<std::shared_ptr<boost::asio::ssl::context>> context = MakeHttpsContext(*tls);
    if (!context.ok()) return context.status();
    options.tls = std::move(context).value();
  }
  Result<std::unique_ptr<foxglove::FoxgloveServer>> listening = foxglove::FoxgloveServer::Listen(
      config.foxglove.address, *map, hub, *latest_scans, query_pool, std::move(options));
  if (!listening.ok()) {
    return Status::FailedPrecondition("server.foxglove.address: " + listening.status().message());
  }
  foxglove = std::move(listening).value();
  foxglove_port = foxglove->port();
  return Status::Ok();
}

// Builds and starts the gRPC server (health, reflection, the map service).
Status MapServer::Impl::ListenGrpc(const std::optional<TlsMaterial>& tls) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(config.listen_address, GrpcCredentials(tls), &port);
  // gRPC sets SO_REUSEPORT by default: a second server on the address would share its calls.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.RegisterService(service.get());
  // A request that does not parse answers INVALID_ARGUMENT naming its type, not UNIMPLEMENTED.
  builder.experimental().SetInterceptorCreators(MapServiceInterceptors());
  const int max_bytes = static_cast<int>(config.limits.max_message_bytes);
  builder.SetMaxReceiveMessageSize(max_bytes);
  builder.SetMaxSendMessageSize(max_bytes);
  server = builder.BuildAndStart();
  if (server == nullptr || port == 0) {
    server.reset();
    return Status::FailedPrecondition("server.listen_address: cannot listen on '" +
                                      config.listen_address +
                                      "' (in use by another process, or not this host's)");
  }
  if (auto* health = server->GetHealthCheckService()) {
    health->SetServingStatus(kMapServiceName, true);
    health->SetServingStatus("", true);
    if (maintenance != nullptr) {
      maintenance->WatchWritable(
          [health](bool writable) { health->SetServingStatus(kWritesHealthName, writable); });
    } else {
      health->SetServingStatus(kWritesHealthName, true);  // a shard: its log takes writes
    }
  }
  return Status::Ok();
}

Result<std::unique_ptr<MapServer>> MapServer::Start(const ServerConfig& config) {
  if (Status s = ValidateServerConfig(config); !s.ok()) return s;
  if (Status s = ValidateSecurity(config); !s.ok()) return s;
  if (Status s = ValidateCluster(config); !s.ok()) return s;
  if (Status s = CheckWorkerCpus(config.worker_cpus); !s.ok()) return s;
  std::optional<TlsMaterial> tls;
  std::unique_ptr<TokenTable> tokens;
  if (Status s = LoadSecurity(config, &tls, &tokens); !s.ok()) return s;
  KeepGrpcInitialized();
  KeepServiceDescriptorLinked();
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(config.map);
  if (!map.ok()) return map.status();
  auto impl = std::make_unique<Impl>(config, std::move(tokens));
  if (config.foxglove.enabled()) {
    impl->latest_scans =
        std::make_unique<LatestScans>(config.limits.max_robots, config.foxglove.max_scan_points);
  }
  if (config.cluster.enabled()) {
    if (Status s = impl->JoinCluster(); !s.ok()) return s;
  } else {
    Result<std::unique_ptr<Durability>> durability = OpenDurability(config, **map);
    if (!durability.ok()) return durability.status();
    impl->OpenServedMap(std::move(map).value(), std::move(durability).value());
  }
  impl->Serve();
  ConfigureWorkerThreads(impl->ingest_pool, ThreadCount(config.worker_threads), config.worker_nice,
                         config.worker_cpus);
  if (!config.metrics_address.empty()) {
    if (Status s = impl->ListenHttp(tls); !s.ok()) return s;
  }
  if (config.foxglove.enabled()) {
    if (Status s = impl->ListenFoxglove(tls); !s.ok()) return s;
  }
  if (impl->maintenance != nullptr) impl->maintenance->Start();
  if (Status s = impl->ListenGrpc(tls); !s.ok()) {
    if (impl->maintenance != nullptr) impl->maintenance->Stop();  // joins its threads
    return s;
  }
  impl->ctx->sessions.StartWatchdog(WatchdogPeriod(config.limits));
  std::string worker_cpus;  // as configured: "any" unpinned, else "1,0"
  for (int cpu : config.worker_cpus) {
    worker_cpus += (worker_cpus.empty() ? "" : ",") + std::to_string(cpu);
  }
  spdlog::info(
      "event=listening address={} port={} worker_threads={} query_threads={} tls={} auth={} "
      "worker_cpus={}",
      config.listen_address, impl->port, ThreadCount(config.worker_threads),
      ThreadCount(config.query_threads),
      !tls.has_value() ? "off" : (tls->client_ca_pem.empty() ? "on" : "mutual"),
      impl->tokens == nullptr ? "off" : std::to_string(impl->tokens->size()) + "_tokens",
      worker_cpus.empty() ? "any" : worker_cpus);
  if (impl->http != nullptr) {
    impl->http->Start();
    spdlog::info("event=metrics_listening address={} port={}", config.metrics_address,
                 impl->http_port);
    spdlog::info("event=web_map_listening url={}://{}:{}/{}", tls.has_value() ? "https" : "http",
                 HostOf(config.metrics_address), impl->http_port,
                 impl->tokens == nullptr ? "" : "login?token=<token>");
  }
  if (impl->foxglove != nullptr) {
    impl->foxglove->Start();
    spdlog::info("event=foxglove_listening url={}://{}:{}/ port={}", tls.has_value() ? "wss" : "ws",
                 HostOf(config.foxglove.address), impl->foxglove_port, impl->foxglove_port);
  }
  return std::unique_ptr<MapServer>(new MapServer(std::move(impl)));
}

int MapServer::port() const { return impl_->port; }

int MapServer::http_port() const { return impl_->http_port; }

int MapServer::foxglove_port() const { return impl_->foxglove_port; }

Status MapServer::ReloadTokens() {
  if (impl_->tokens == nullptr) {
    spdlog::info("event=tokens_reload_skipped reason=\"server.auth.tokens_file is not set\"");
    return Status::FailedPrecondition("server.auth.tokens_file is not set; nothing to reload");
  }
  if (Status s = impl_->tokens->Reload(); !s.ok()) {
    spdlog::error("event=tokens_reload_failed tokens={} reason=\"{}\" (the previous tokens stay)",
                  impl_->tokens->size(), s.message());
    return s;
  }
  spdlog::info("event=tokens_reloaded file={} tokens={}", impl_->tokens->path(),
               impl_->tokens->size());
  return Status::Ok();
}

void MapServer::Shutdown() {
  std::lock_guard lock(impl_->shutdown_mu);
  if (impl_->stopped) return;
  impl_->stopped = true;
  const auto t0 = std::chrono::steady_clock::now();
  spdlog::info("event=shutdown_begin open_ingest_streams={} watchers={}",
               impl_->ctx->sessions.count(SessionRegistry::Kind::kIngest),
               impl_->ctx->sessions.count(SessionRegistry::Kind::kWatch));
  if (auto* health = impl_->server->GetHealthCheckService()) {
    if (impl_->maintenance != nullptr) impl_->maintenance->WatchWritable(nullptr);
    health->SetServingStatus(kMapServiceName, false);
    health->SetServingStatus(kWritesHealthName, false);
  }
  // Ingest streams stop reading and ack what they have; watches end.
  impl_->ctx->sessions.DrainAll();
  // Refuse new calls and wait for the open ones (bounded by the grace period).
  const auto grace = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::duration<double>(impl_->config.shutdown_timeout_s));
  impl_->server->Shutdown(std::chrono::system_clock::now() + grace);
  impl_->ctx->sessions.StopWatchdog();
  if (impl_->served != nullptr) impl_->served->WaitIdle();
  // Scrapes see the drain above; the endpoint closes before the store and the pools do.
  if (impl_->web != nullptr) impl_->web->Stop();  // event streams end before their server
  if (impl_->http != nullptr) impl_->http->Stop();
  if (impl_->foxglove != nullptr) impl_->foxglove->Stop();
  if (impl_->maintenance != nullptr) impl_->maintenance->Stop();
  if (std::optional<StoreStatus> store =
          impl_->served != nullptr ? impl_->served->store_status() : std::nullopt) {
    // Last checkpoint: the next start replays nothing.
    const Status s = impl_->served->Checkpoint();
    store = impl_->served->store_status();
    spdlog::info(
        "event=storage_closed data_dir={} durability={} checkpoint_version={} corrupt_tiles={} "
        "checkpoint={}",
        store->directory, store->durability, store->checkpoint_version, store->corrupt_tiles,
        s.ok() ? "ok" : s.message());
  }
  if (impl_->served != nullptr) impl_->served->StopScratchRelease();
  impl_->ingest_pool.join();
  impl_->query_pool.join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  spdlog::info("event=shutdown_done seconds={:.3f}", seconds);
}

ServerReport MapServer::Report() const {
  ServerReport r;
  // (State() recounts the tiles changed since the last read.)
  MapState state = impl_->map->State();
  r.map_version = state.version;
  r.scans_applied = state.scans_applied;
  r.tile_count = state.summary.tile_count;
  r.known_cells = state.summary.known_cells;
  if (impl_->served != nullptr) {
    r.peak_parallel_integrations = impl_->served->peak_parallel_integrations();
    r.banded_scans = impl_->served->banded_scans();
  }
  r.robots = std::move(state.robots);
  return r;
}

std::unique_ptr<TerrainMap> MapServer::SnapshotMap() const {
  if (impl_->served != nullptr) return impl_->served->Snapshot();
  return TerrainMap::Create(impl_->config.map).value();  // a shard's own map: empty
}

}  // namespace bgkmap
