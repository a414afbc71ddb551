// ImportMap (admin): adds an uploaded archive's statistics into the served map, as one change.
//
//   1. The chunks are spooled to a file (the store's tmp/ directory, or the system's temporary
//      directory for a map in memory), refusing more than server.max_import_bytes.
//   2. The whole file is read and verified (archive_upload.h) before anything changes.
//   3. ServedMap::SubmitImport adds the tiles as one exclusive change with its own map version,
//      checkpointed at once; if that write fails the tiles are put back as they were and the
//      call answers UNAVAILABLE, nothing imported.
// The spool file is removed in every outcome. Robots' sequence numbers are not touched.
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <filesystem>
#include <optional>

#include "rpc/archive_upload.h"
#include "rpc/handlers/handlers.h"

namespace bgkmap {
namespace {

class ImportStream final : public grpc::ServerReadReactor<v1::ArchiveChunk> {
 public:
  ImportStream(ServiceContext& ctx, v1::ImportResponse* response) : ctx_(ctx), response_(response) {
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
      End({grpc::StatusCode::UNAVAILABLE,
           "archive not imported: cannot spool it: " + spool.status().message()});
      return;
    }
    spool_ = std::move(*spool);
    start_ = std::chrono::steady_clock::now();
    StartRead(&chunk_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // the client finished sending (or the call ended)
      boost::asio::post(ctx_.query_pool, [this] { VerifyAndSubmit(); });
      return;
    }
    if (spool_->size() + chunk_.data().size() > ctx_.limits.max_import_bytes) {
      End({grpc::StatusCode::RESOURCE_EXHAUSTED, "archive: more than server.max_import_bytes = " +
                                                     std::to_string(ctx_.limits.max_import_bytes) +
                                                     " bytes; nothing imported"});
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] {
      if (Status s = spool_->Append(chunk_.data()); !s.ok()) {
        End({grpc::StatusCode::UNAVAILABLE, "archive not imported: " + s.message()});
        return;
      }
      StartRead(&chunk_);
    });
  }

  void OnCancel() override { cancelled_.store(true); }

  void OnDone() override { delete this; }

 private:
  // Frees the import slot and the spool file before the client hears the outcome, so that its
  // next import is not refused as concurrent with this one.
  void End(const grpc::Status& status) {
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
    grpc::Status verified = ReadVerifiedArchive(spool_->path(), ctx_.map.params(), &archive_);
    spool_.reset();  // the tiles are in memory now
    if (!verified.ok()) {
      spdlog::warn("event=import_refused bytes={} reason=\"{}\"", bytes, verified.error_message());
      End(verified);
      return;
    }
    if (cancelled_.load()) {
      End({grpc::StatusCode::CANCELLED, "import cancelled; nothing imported"});
      return;
    }
    bytes_ = bytes;
    ctx_.map.SubmitImport(archive_.keys, archive_.tiles,
                          [this](const ImportOutcome& outcome) { Done(outcome); });
  }

  void Done(const ImportOutcome& outcome) {
    const Status& status = outcome.status;
    if (!status.ok()) {
      spdlog::error("event=import_not_applied version={} reason=\"{}\"", outcome.version,
                    status.message());
      End({status.code() == Status::Code::kDataLoss ? grpc::StatusCode::DATA_LOSS
                                                    : grpc::StatusCode::UNAVAILABLE,
           "archive not imported: " + status.message()});
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
      End(grpc::Status::OK);
    });
  }

  ServiceContext& ctx_;
  v1::ImportResponse* response_;
  std::optional<Permit> permit_;  // one import at a time
  std::unique_ptr<SpoolFile> spool_;
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> cancelled_{false};
  v1::ArchiveChunk chunk_;
  VerifiedArchive archive_;
  uint64_t bytes_ = 0;
};

}  // namespace

grpc::ServerReadReactor<v1::ArchiveChunk>* StartImportMap(ServiceContext& ctx,
                                                          v1::ImportResponse* response) {
  return new ImportStream(ctx, response);
}

}  // namespace bgkmap
