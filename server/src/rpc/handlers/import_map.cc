// ImportMap (admin): adds an uploaded archive's statistics into the map, as one change.
//
//   1. The chunks go to the map's upload (MapWrites::BeginImport: spooled to a file in the
//      store's tmp/ directory, or the system's temporary directory for a map in memory),
//      refusing more than server.max_import_bytes.
//   2. The whole upload is read and verified before anything changes.
//   3. The map adds the tiles as one change with its own version (a single server: checkpointed
//      at once, and put back as they were if that write fails; a cluster: one entry of its log).
// The spool file is removed in every outcome. Robots' sequence numbers are not touched. A map in
// a local frame takes the archive's georeference, if it has one (one that differs is refused).
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>

#include "bgkmap/server/log_safe.h"
#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"

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
    Result<std::unique_ptr<ArchiveUpload>> upload = ctx.map.BeginImport();
    if (!upload.ok()) {
      End({grpc::StatusCode::UNAVAILABLE, "archive not imported: " + upload.status().message()});
      return;
    }
    upload_ = std::move(upload).value();
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
    if (upload_->size() + chunk_.data().size() > ctx_.limits.max_import_bytes) {
      End({grpc::StatusCode::INVALID_ARGUMENT, "archive: more than server.max_import_bytes = " +
                                                   std::to_string(ctx_.limits.max_import_bytes) +
                                                   " bytes; nothing imported"});
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] {
      if (Status s = upload_->Append(chunk_.data()); !s.ok()) {
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
      spool_bytes_.store(upload_->size());
    }
    StartRead(&chunk_);
  }

  // Frees the import slot and the spooled upload before the client hears the outcome, so that its
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
    upload_.reset();
    permit_.reset();
    Finish(status);
  }

  void VerifyAndSubmit() {
    upload_->Submit([this] { return cancelled_.load(); },
                    [this](const ImportOutcome& outcome) { Done(outcome); });
  }

  // The client's status for an import that stopped, by where it stopped.
  static grpc::Status Refusal(const ImportOutcome& outcome) {
    const Status& s = outcome.status;
    const Status::Code code = s.code();
    switch (outcome.stage) {
      case ImportStage::kSpool:
        return {grpc::StatusCode::UNAVAILABLE, "archive not imported: " + s.message()};
      case ImportStage::kCheck:
        return ToGrpcStatus(s);
      case ImportStage::kGeoreference:
        return {code == Status::Code::kFailedPrecondition ? grpc::StatusCode::FAILED_PRECONDITION
                                                          : grpc::StatusCode::UNAVAILABLE,
                "archive not imported: cannot keep its georeference: " + s.message()};
      case ImportStage::kChange:
        break;
    }
    const grpc::StatusCode grpc_code = code == Status::Code::kDataLoss ? grpc::StatusCode::DATA_LOSS
                                       : code == Status::Code::kOutOfRange  // a sum overflows
                                           ? grpc::StatusCode::OUT_OF_RANGE
                                           : grpc::StatusCode::UNAVAILABLE;
    return {grpc_code, "archive not imported: " + s.message() + "; nothing imported"};
  }

  void Done(const ImportOutcome& outcome) {
    if (outcome.cancelled) {
      End({grpc::StatusCode::CANCELLED, "import cancelled; nothing imported"});
      return;
    }
    if (!outcome.status.ok()) {
      if (outcome.stage == ImportStage::kChange) {
        spdlog::error("event=import_not_applied version={} reason=\"{}\"", outcome.version,
                      LogSafe(outcome.status.message()));
      }
      End(Refusal(outcome));
      return;
    }
    response_->set_tiles_added(outcome.tiles_added);
    response_->set_map_version(outcome.version);
    response_->set_archive_map_version(outcome.archive_map_version);
    boost::asio::post(ctx_.query_pool, [this, outcome] {
      response_->set_known_cells(ctx_.map.State().summary.known_cells);
      spdlog::info(
          "event=import_map version={} tiles={} archive_known_cells={} bytes={} seconds={:.3f}",
          response_->map_version(), response_->tiles_added(), outcome.archive_known_cells,
          outcome.bytes,
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
  std::unique_ptr<ArchiveUpload> upload_;
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> cancelled_{false};
  std::atomic<uint64_t> spool_bytes_{0};  // for the log
  v1::ArchiveChunk chunk_;

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
