// ImportMap (admin): adds an uploaded archive's statistics into the served map, as one change.
//
//   1. The chunks are spooled to a file (the store's tmp/ directory, or the system's temporary
//      directory for a map in memory), refusing more than server.max_import_bytes.
//   2. The whole file is read and verified (archive_upload.h) before anything changes.
//   3. ServedMap::SubmitImport adds the tiles as one exclusive change with its own map version,
//      checkpointed at once; if that write fails the tiles are put back as they were and the
//      call answers UNAVAILABLE, nothing imported.
// The spool file is removed in every outcome. Robots' sequence numbers are not touched. A map in
// a local frame takes the archive's georeference, if it has one (one that differs is refused).
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>

#include "cluster/cluster_node.h"
#include "log_safe.h"
#include "rpc/archive_upload.h"
#include "rpc/handlers/handlers.h"

namespace bgkmap {
namespace {

class ImportStream final : public grpc::ServerReadReactor<v1::ArchiveChunk>, public DrainListener {
 public:
  ImportStream(ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who,
               v1::ImportResponse* response)
      : ctx_(ctx),
        who_(std::move(who)),
        peer_(call->peer()),
        response_(response),
        idle_timeout_(TimeoutOf(ctx.limits.import_idle_timeout_s)) {
    permit_.emplace(ctx.imports, 1);
    if (!*permit_) {
      End({grpc::StatusCode::RESOURCE_EXHAUSTED, "an import is already running; retry later"});
      return;
    }
    if (ctx.sessions.draining()) {
      End({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
      return;
    }
    const Durability::ScratchDirectory dir = ctx.map.scratch_directory();
    // Imports run one at a time: any other spool file there is a crash's leftover.
    if (dir.exclusive) RemoveStaleSpoolFiles(dir.path);
    Result<std::unique_ptr<SpoolFile>> spool = SpoolFile::Create(dir.path);
    if (!spool.ok()) {
      // The directory is the operator's business, not the client's.
      spdlog::error("event=import_spool_failed dir=\"{}\" reason=\"{}\"", LogSafe(dir.path),
                    LogSafe(spool.status().message()));
      End({grpc::StatusCode::UNAVAILABLE,
           "archive not imported: cannot spool it: " + spool.status().message()});
      return;
    }
    spool_ = std::move(*spool);
    start_ = std::chrono::steady_clock::now();
    // An upload that stops sending gives the import slot back (server.import_idle_timeout_s).
    registered_ = ctx_.sessions.Add(this, SessionRegistry::Kind::kStream, UINT32_MAX) ==
                  SessionRegistry::Admit::kOk;
    ReadNext();
  }

  void OnReadDone(bool ok) override {
    {
      std::lock_guard lock(mu_);
      reading_ = false;
      if (finished_) return;  // a read that was pending when the call ended
    }
    if (!ok) {  // the client finished sending (or the call ended)
      if (cancelled_.load()) {
        End({grpc::StatusCode::CANCELLED, "import cancelled; nothing imported"});
        return;
      }
      boost::asio::post(ctx_.query_pool, [this] { VerifyAndSubmit(); });
      return;
    }
    if (spool_->size() + chunk_.data().size() > ctx_.limits.max_import_bytes) {
      End({grpc::StatusCode::INVALID_ARGUMENT, "archive: more than server.max_import_bytes = " +
                                                   std::to_string(ctx_.limits.max_import_bytes) +
                                                   " bytes; nothing imported"});
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] {
      // The spool shares the store's disk: it must not eat the reserve RocksDB relies on.
      if (Status s = ctx_.map.AdmitScratch(chunk_.data().size()); !s.ok()) {
        End({grpc::StatusCode::UNAVAILABLE, "archive not imported: " + s.message()});
        return;
      }
      if (Status s = spool_->Append(chunk_.data()); !s.ok()) {
        End({grpc::StatusCode::UNAVAILABLE, "archive not imported: " + s.message()});
        return;
      }
      ReadNext();
    });
  }

  void OnCancel() override { cancelled_.store(true); }

  void OnDone() override {
    if (registered_) ctx_.sessions.Remove(this);
    delete this;
  }

  // The drain lets an upload finish (bounded by the shutdown grace).
  void BeginDrain() override {}

  void Tick(std::chrono::steady_clock::time_point now) override {
    {
      // Decided and marked under the lock: a chunk arriving now finds the call finished and
      // leaves the spool file alone.
      std::lock_guard lock(mu_);
      if (finished_ || !reading_ || idle_timeout_ == std::chrono::steady_clock::duration::zero() ||
          now - last_chunk_ <= idle_timeout_) {
        return;
      }
      finished_ = true;
    }
    spdlog::warn("event=import_idle bytes={}", spool_bytes_.load());
    Conclude({grpc::StatusCode::DEADLINE_EXCEEDED,
              "archive: no chunk for server.import_idle_timeout_s = " +
                  SecondsText(ctx_.limits.import_idle_timeout_s) + " s; nothing imported"});
  }

 private:
  void ReadNext() {
    {
      std::lock_guard lock(mu_);
      if (finished_) return;
      reading_ = true;
      last_chunk_ = std::chrono::steady_clock::now();
      spool_bytes_.store(spool_->size());
    }
    StartRead(&chunk_);
  }

  // Frees the import slot and the spool file before the client hears the outcome, so that its
  // next import is not refused as concurrent with this one. Only the first call counts.
  void End(const grpc::Status& status) {
    {
      std::lock_guard lock(mu_);
      if (finished_) return;
      finished_ = true;
    }
    Conclude(status);
  }
  void Conclude(const grpc::Status& status) {
    spool_.reset();
    permit_.reset();
    Finish(status);
  }

  void VerifyAndSubmit() {
    const uint64_t bytes = spool_->size();
    if (Status s = spool_->Close(); !s.ok()) {
      End({grpc::StatusCode::UNAVAILABLE, "archive not imported: " + s.message()});
      return;
    }
    grpc::Status verified =
        ReadVerifiedArchive(spool_->path(), ctx_.map.params(), ctx_.map.georeference(), &archive_);
    spool_.reset();  // the tiles are in memory now
    if (!verified.ok()) {
      spdlog::warn("event=import_refused bytes={} reason=\"{}\"", bytes,
                   LogSafe(verified.error_message()));
      End(verified);
      return;
    }
    if (cancelled_.load()) {
      End({grpc::StatusCode::CANCELLED, "import cancelled; nothing imported"});
      return;
    }
    // A map in a local frame takes a georeferenced archive's frame, before its tiles: the
    // tiles are placed by it (imports run one at a time, so nothing adopts another meanwhile).
    if (Status s = ctx_.map.AdoptGeoreference(archive_.metadata.georeference); !s.ok()) {
      End({s.code() == Status::Code::kFailedPrecondition ? grpc::StatusCode::FAILED_PRECONDITION
                                                         : grpc::StatusCode::UNAVAILABLE,
           "archive not imported: cannot keep its georeference: " + s.message()});
      return;
    }
    bytes_ = bytes;
    if (ctx_.cluster != nullptr) {
      // One entry of the cluster's log (the tiles stored beside it): every shard adds them in
      // the log's order. Not checked here for sums that overflow (no shard holds every tile).
      Result<uint64_t> appended = ctx_.cluster->AppendImport(archive_.keys, archive_.tiles);
      Done(appended.ok() ? ImportOutcome{*appended, Status::Ok()}
                         : ImportOutcome{0, appended.status()});
      return;
    }
    ctx_.map.SubmitImport(archive_.keys, archive_.tiles,
                          [this](const ImportOutcome& outcome) { Done(outcome); });
  }

  static grpc::StatusCode CodeOf(const Status& status) {
    switch (status.code()) {
      case Status::Code::kDataLoss:
        return grpc::StatusCode::DATA_LOSS;
      case Status::Code::kOutOfRange:  // the sums would overflow
        return grpc::StatusCode::OUT_OF_RANGE;
      default:
        return grpc::StatusCode::UNAVAILABLE;
    }
  }

  void Done(const ImportOutcome& outcome) {
    const Status& status = outcome.status;
    if (!status.ok()) {
      spdlog::error("event=import_not_applied version={} reason=\"{}\"", outcome.version,
                    LogSafe(status.message()));
      End({CodeOf(status), "archive not imported: " + status.message() + "; nothing imported"});
      return;
    }
    response_->set_tiles_added(archive_.keys.size());
    response_->set_map_version(outcome.version);
    response_->set_archive_map_version(archive_.metadata.map_version);
    archive_.tiles.clear();
    boost::asio::post(ctx_.query_pool, [this] {
      response_->set_known_cells(ctx_.map.Summary().known_cells);
      spdlog::info(
          "event=import_map version={} tiles={} archive_known_cells={} bytes={} seconds={:.3f}",
          response_->map_version(), response_->tiles_added(), archive_.known_cells, bytes_,
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
      AuditLog(*who_, "import_map",
               "tiles=" + std::to_string(response_->tiles_added()) +
                   " archive_map_version=" + std::to_string(response_->archive_map_version()),
               response_->map_version(), peer_);
      End(grpc::Status::OK);
    });
  }

  ServiceContext& ctx_;
  const PrincipalRef who_;
  const std::string peer_;
  v1::ImportResponse* response_;
  const std::chrono::steady_clock::duration idle_timeout_;
  bool registered_ = false;
  std::optional<Permit> permit_;  // one import at a time
  std::unique_ptr<SpoolFile> spool_;
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> cancelled_{false};
  std::atomic<uint64_t> spool_bytes_{0};  // for the log
  v1::ArchiveChunk chunk_;
  VerifiedArchive archive_;
  uint64_t bytes_ = 0;

  std::mutex mu_;
  bool reading_ = false;   // a read is outstanding
  bool finished_ = false;  // End() was called
  std::chrono::steady_clock::time_point last_chunk_;
};

}  // namespace

grpc::ServerReadReactor<v1::ArchiveChunk>* StartImportMap(ServiceContext& ctx,
                                                          grpc::CallbackServerContext* call,
                                                          PrincipalRef who,
                                                          v1::ImportResponse* response) {
  return new ImportStream(ctx, call, std::move(who), response);
}

}  // namespace bgkmap
