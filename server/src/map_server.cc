#include "bgkmap/server/map_server.h"

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <malloc.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <boost/asio/post.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <condition_variable>
#include <future>
#include <latch>
#include <mutex>
#include <thread>

#include "bgkmap/v1/map_service.pb.h"
#include "map_service.h"
#include "metrics.h"
#include "metrics_http.h"
#include "service_context.h"

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

// storage.max_memory_mb bounds the map's memory: the tiles in memory, plus the copies of the
// changed ones that a checkpoint holds while it writes them (a copy, and its encoding in the
// write). Tiles get two thirds of the bound; changed tiles are kept to a quarter of that by
// checkpointing, so a checkpoint holds at most the remaining third.
uint64_t TileMemoryLimit(const StorageConfig& storage) {
  return (storage.max_memory_mb << 20) / 3 * 2;
}

// Lowers the scheduling priority of every thread of `pool` by `nice` (Linux: per thread). Each
// thread takes exactly one task: all of them wait until every one has started.
void LowerPriority(boost::asio::thread_pool& pool, size_t threads, int nice) {
  if (nice == 0) return;
  auto started = std::make_shared<std::latch>(static_cast<std::ptrdiff_t>(threads));
  for (size_t i = 0; i < threads; ++i) {
    boost::asio::post(pool, [started, nice] {
      if (setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice) != 0) {
        spdlog::warn("event=worker_nice_failed errno={}", errno);
      }
      started->arrive_and_wait();
    });
  }
  started->wait();
}

size_t ThreadCount(int configured) {
  if (configured > 0) return static_cast<size_t>(configured);
  return std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace

struct MapServer::Impl {
  Impl(const ServerConfig& cfg, std::unique_ptr<TerrainMap> map,
       std::unique_ptr<MapPersistence> persisted)
      : config(cfg),
        persistence(std::move(persisted)),
        ingest_pool(ThreadCount(cfg.worker_threads)),
        query_pool(ThreadCount(cfg.query_threads)),
        store(std::move(map)),
        scheduler(store, ingest_pool, cfg.limits.max_robots,
                  [this](const std::vector<TileKey>& changed) { hub.Publish(changed); }),
        ctx(cfg, store, scheduler, hub, ingest_pool, query_pool),
        service(ctx) {}

  // Takes a checkpoint at a scheduler barrier and writes it; returns the write's status.
  Status Checkpoint();
  void CheckpointLoop();
  void StopCheckpoints();
  // Keeps the tiles in memory under storage.max_memory_mb (a thread, woken by the map store).
  void EvictionLoop();
  void RequestEviction();

  ServerConfig config;
  std::unique_ptr<MapPersistence> persistence;  // outlives the workers that journal into it
  boost::asio::thread_pool ingest_pool;
  boost::asio::thread_pool query_pool;
  MapStore store;
  WatchHub hub;
  ScanScheduler scheduler;
  ServiceContext ctx;
  MapService service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;

  std::mutex shutdown_mu;
  bool stopped = false;

  std::thread checkpointer;
  std::mutex checkpoint_mu;
  std::condition_variable checkpoint_cv;
  bool stop_checkpoints = false;

  std::thread evictor;
  std::thread verifier;
  std::atomic<bool> stop_verifying{false};
  bool eviction_requested = false;  // guarded by checkpoint_mu, signalled by checkpoint_cv

  // GET /metrics (server.metrics_address); null when off. Last: it reads everything above.
  std::unique_ptr<MetricsHttpServer> metrics;
  int metrics_port = 0;
};

void MapServer::Impl::RequestEviction() {
  {
    std::lock_guard lock(checkpoint_mu);
    if (eviction_requested) return;
    eviction_requested = true;
  }
  checkpoint_cv.notify_all();
}

void MapServer::Impl::EvictionLoop() {
  const uint64_t limit = TileMemoryLimit(config.storage);
  // Evict to below the bound, so that eviction runs in batches rather than after every scan.
  const uint64_t target = limit / 10 * 8;
  // A checkpoint makes changed tiles evictable, but it writes every changed tile: when the
  // bound is smaller than what is being changed, take one at most this often.
  constexpr auto kMinCheckpointGap = std::chrono::milliseconds(20);
  auto last_checkpoint = std::chrono::steady_clock::now() - kMinCheckpointGap;
  std::unique_lock lock(checkpoint_mu);
  while (!stop_checkpoints) {
    checkpoint_cv.wait_for(lock, std::chrono::seconds(1),
                           [this] { return stop_checkpoints || eviction_requested; });
    if (stop_checkpoints) break;
    eviction_requested = false;
    lock.unlock();
    const uint64_t evicted_before = store.Residency().tiles_evicted;
    uint64_t held = store.Evict(target);
    if ((held > limit || persistence->dirty_over_limit()) &&
        std::chrono::steady_clock::now() - last_checkpoint >= kMinCheckpointGap) {
      const Status s = Checkpoint();
      last_checkpoint = std::chrono::steady_clock::now();
      if (s.ok()) held = store.Evict(target);
    }
    // Hand the freed tiles back to the system: the heap keeps large free blocks otherwise
    // (KeepLargeAllocationsInHeap), and the bound is about the process's memory.
    if (store.Residency().tiles_evicted != evicted_before) malloc_trim(0);
    lock.lock();
    if (held > limit && !eviction_requested) {
      // Still over (tiles in use or the checkpoint gap): look again soon.
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      lock.lock();
      eviction_requested = true;
    }
  }
}

Status MapServer::Impl::Checkpoint() {
  std::promise<CapturedCheckpoint> captured;
  std::future<CapturedCheckpoint> ready = captured.get_future();
  scheduler.SubmitBarrier([this, &captured](uint64_t applied) {
    if (persistence->write_failed()) {
      const Status resumed = persistence->ResumeIfFailed();
      if (resumed.ok()) {
        spdlog::info("event=storage_resumed");
      } else {
        spdlog::warn("event=storage_resume_failed reason=\"{}\"", resumed.message());
      }
    }
    captured.set_value(persistence->Capture(store, applied));
  });
  CapturedCheckpoint c = ready.get();
  const auto t0 = std::chrono::steady_clock::now();
  const size_t tiles = c.keys.size();
  const uint64_t version = c.version;
  Status s = persistence->Write(std::move(c));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (s.ok()) {
    spdlog::info("event=checkpoint version={} tiles={} seconds={:.3f}", version, tiles, seconds);
  } else {
    spdlog::error("event=checkpoint_failed version={} reason=\"{}\"", version, s.message());
  }
  return s;
}

void MapServer::Impl::CheckpointLoop() {
  const auto interval = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::duration<double>(config.storage.checkpoint_interval_s));
  std::unique_lock lock(checkpoint_mu);
  // After a write failure, checkpoint (which first resumes the store) every second rather than
  // every interval, so ingestion comes back soon after the disk has room.
  const auto tick =
      std::clamp(interval, std::chrono::milliseconds(1), std::chrono::milliseconds(1000));
  auto last = std::chrono::steady_clock::now();
  while (!checkpoint_cv.wait_for(lock, tick, [this] { return stop_checkpoints; })) {
    if (!persistence->write_failed() && std::chrono::steady_clock::now() - last < interval) {
      continue;
    }
    lock.unlock();
    (void)Checkpoint();  // a failure is logged; the log keeps the changes
    lock.lock();
    last = std::chrono::steady_clock::now();
  }
}

void MapServer::Impl::StopCheckpoints() {
  {
    std::lock_guard lock(checkpoint_mu);
    stop_checkpoints = true;
  }
  checkpoint_cv.notify_all();
  stop_verifying.store(true);
  if (checkpointer.joinable()) checkpointer.join();
  if (evictor.joinable()) evictor.join();
  if (verifier.joinable()) verifier.join();
}

void KeepLargeAllocationsInHeap() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

MapServer::MapServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

MapServer::~MapServer() { Shutdown(); }

Result<std::unique_ptr<MapServer>> MapServer::Start(const ServerConfig& config) {
  if (Status s = ValidateServerConfig(config); !s.ok()) return s;
  KeepGrpcInitialized();
  KeepServiceDescriptorLinked();
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(config.map);
  if (!map.ok()) return map.status();
  std::unique_ptr<MapPersistence> persistence;
  if (!config.storage.data_dir.empty()) {
    Result<std::unique_ptr<MapPersistence>> opened =
        MapPersistence::Open(config.storage, config.map, **map);
    if (!opened.ok()) return opened.status();
    persistence = std::move(opened).value();
    const storage::RecoveryReport& r = persistence->recovery();
    spdlog::info(
        "event=recovered data_dir={} durability={} checkpoint_version={} map_version={} "
        "scans_replayed={} clears_replayed={} tiles={} corrupt_records={} corrupt_tiles={} "
        "seconds={:.3f}",
        persistence->directory(), persistence->durability(), r.checkpoint_version, r.map_version,
        r.scans_replayed, r.clears_replayed, (*map)->tile_count(), r.corrupt_records.size(),
        persistence->CorruptTiles().size(), r.seconds);
  }
  auto impl = std::make_unique<Impl>(config, std::move(map).value(), std::move(persistence));
  LowerPriority(impl->ingest_pool, ThreadCount(config.worker_threads), config.worker_nice);
  if (!config.metrics_address.empty()) {
    // Bound before any thread starts, so that a bad address fails the start cleanly; served
    // once the map service is up.
    Result<std::unique_ptr<MetricsHttpServer>> metrics = MetricsHttpServer::Listen(
        config.metrics_address, [p = impl.get()] { return FormatMetrics(CollectMetrics(p->ctx)); });
    if (!metrics.ok()) {
      return Status::FailedPrecondition("server.metrics_address: " + metrics.status().message());
    }
    impl->metrics = std::move(metrics).value();
    impl->metrics_port = impl->metrics->port();
  }
  if (impl->persistence != nullptr) {
    impl->scheduler.Restore(impl->persistence->map_version(), impl->persistence->RobotSequences());
    impl->scheduler.SetJournal(impl->persistence.get());
    impl->ctx.persistence = impl->persistence.get();
    impl->store.AttachBacking(impl->persistence.get(), TileMemoryLimit(config.storage),
                              [p = impl.get()] { p->RequestEviction(); });
    impl->checkpointer = std::thread([p = impl.get()] { p->CheckpointLoop(); });
    if (config.storage.max_memory_mb > 0) {
      impl->persistence->SetDirtyLimit(
          std::max<size_t>(1, TileMemoryLimit(config.storage) / 4 / impl->store.TileBytes()),
          [p = impl.get()] { p->RequestEviction(); });
      impl->evictor = std::thread([p = impl.get()] { p->EvictionLoop(); });
    }
    if (config.storage.verify_on_start) {
      impl->verifier = std::thread([p = impl.get()] {
        const MapPersistence::VerifyReport r = p->persistence->VerifyStoredTiles(p->stop_verifying);
        spdlog::info(
            "event=verify_done tiles={} corrupt_tiles={} unreadable_tiles={} stopped={} "
            "seconds={:.3f}",
            r.tiles, r.corrupt, r.unreadable, r.stopped, r.seconds);
      });
    }
  }

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(config.listen_address, grpc::InsecureServerCredentials(), &impl->port);
  builder.RegisterService(&impl->service);
  const int max_bytes = static_cast<int>(config.limits.max_message_bytes);
  builder.SetMaxReceiveMessageSize(max_bytes);
  builder.SetMaxSendMessageSize(max_bytes);
  impl->server = builder.BuildAndStart();
  if (impl->server == nullptr || impl->port == 0) {
    impl->server.reset();
    impl->StopCheckpoints();  // joins the store's threads (a joinable std::thread terminates)
    return Status::FailedPrecondition("server.listen_address: cannot listen on '" +
                                      config.listen_address + "'");
  }
  if (auto* health = impl->server->GetHealthCheckService()) {
    health->SetServingStatus(kMapServiceName, true);
    health->SetServingStatus("", true);
  }
  spdlog::info("event=listening address={} port={} worker_threads={} query_threads={}",
               config.listen_address, impl->port, ThreadCount(config.worker_threads),
               ThreadCount(config.query_threads));
  if (impl->metrics != nullptr) {
    impl->metrics->Start();
    spdlog::info("event=metrics_listening address={} port={}", config.metrics_address,
                 impl->metrics_port);
  }
  return std::unique_ptr<MapServer>(new MapServer(std::move(impl)));
}

int MapServer::port() const { return impl_->port; }

int MapServer::metrics_port() const { return impl_->metrics_port; }

void MapServer::Shutdown() {
  std::lock_guard lock(impl_->shutdown_mu);
  if (impl_->stopped) return;
  impl_->stopped = true;
  const auto t0 = std::chrono::steady_clock::now();
  spdlog::info("event=shutdown_begin open_ingest_streams={} watchers={}",
               impl_->ctx.sessions.count(SessionRegistry::Kind::kIngest),
               impl_->ctx.sessions.count(SessionRegistry::Kind::kWatch));
  if (auto* health = impl_->server->GetHealthCheckService()) {
    health->SetServingStatus(kMapServiceName, false);
  }
  // Ingest streams stop reading and ack what they have; watches end.
  impl_->ctx.sessions.DrainAll();
  // Refuse new calls and wait for the open ones (bounded by the grace period).
  const auto grace = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::duration<double>(impl_->config.shutdown_timeout_s));
  impl_->server->Shutdown(std::chrono::system_clock::now() + grace);
  impl_->scheduler.WaitIdle();
  // Scrapes see the drain above; the endpoint closes before the store and the pools do.
  if (impl_->metrics != nullptr) impl_->metrics->Stop();
  if (impl_->persistence != nullptr) {
    // Last checkpoint: the next start replays nothing.
    impl_->StopCheckpoints();
    const Status s = impl_->Checkpoint();
    spdlog::info(
        "event=storage_closed data_dir={} durability={} checkpoint_version={} corrupt_tiles={} "
        "checkpoint={}",
        impl_->persistence->directory(), impl_->persistence->durability(),
        impl_->persistence->checkpoint_version(), impl_->persistence->CorruptTiles().size(),
        s.ok() ? "ok" : s.message());
  }
  impl_->ingest_pool.join();
  impl_->query_pool.join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  spdlog::info("event=shutdown_done seconds={:.3f}", seconds);
}

ServerReport MapServer::Report() const {
  ServerReport r;
  r.map_version = impl_->scheduler.applied_version();
  r.scans_applied = impl_->scheduler.scans_applied();
  const MapSummary summary = impl_->store.Summarize();
  r.tile_count = summary.tile_count;
  r.known_cells = summary.known_cells;
  r.peak_parallel_integrations = impl_->store.peak_parallel_integrations();
  for (const RobotProgress& p : impl_->scheduler.Robots()) {
    r.robots.push_back(
        {p.robot_id, p.last_sequence, p.scans_applied, p.scans_duplicate, p.scans_rejected});
  }
  return r;
}

std::unique_ptr<TerrainMap> MapServer::SnapshotMap() const { return impl_->store.Snapshot(); }

}  // namespace bgkmap
