// ExportMap (admin): the map, or the cells of a box, as one archive, streamed in chunks. The
// archive is a consistent snapshot at one map version V (MapWrites::SubmitExport), encoded as it
// is read while ingestion goes on. A stored tile that fails its checksum fails the call with
// DATA_LOSS naming it: no archive is ever silently wrong.
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <cstdint>
#include <optional>

#include "rpc/handlers/handlers.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

class ExportStream final : public grpc::ServerWriteReactor<v1::ArchiveChunk> {
 public:
  ExportStream(ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who,
               const v1::ExportRequest& request)
      : ctx_(ctx),
        who_(std::move(who)),
        peer_(call->peer()),
        permit_(ctx, *who_),
        stalled_(call, ctx.limits.stalled_write_timeout_s) {
    if (!permit_) {
      Finish(permit_.refusal());
      return;
    }
    if (ctx.sessions.draining()) {
      Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
      return;
    }
    if (request.has_box()) {
      CellBox box;
      if (grpc::Status s = RegionCells(request.box(), "box", ctx.map.geometry(), 1, ctx.limits,
                                       /*limit_cells=*/false, &box);
          !s.ok()) {
        Finish(s);
        return;
      }
      box_ = box;
    }
    start_ = std::chrono::steady_clock::now();
    // A client that stops reading gives its slot and the store's snapshot back.
    registered_ = ctx_.sessions.Add(&stalled_, SessionRegistry::Kind::kStream, UINT32_MAX) ==
                  SessionRegistry::Admit::kOk;
    ctx_.map.SubmitExport(box_, [this](Result<std::unique_ptr<ArchiveChunks>> archive) {
      auto shared = std::make_shared<Result<std::unique_ptr<ArchiveChunks>>>(std::move(archive));
      boost::asio::post(ctx_.query_pool, [this, shared] { Start(std::move(*shared)); });
    });
  }

  void OnWriteDone(bool ok) override {
    stalled_.WriteDone();
    if (!ok) {
      archive_.reset();  // the store's snapshot goes now, not when the call is done
      Finish({grpc::StatusCode::CANCELLED, "export stream cancelled"});
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] { SendNext(); });
  }

  void OnDone() override {
    if (registered_) ctx_.sessions.Remove(&stalled_);
    delete this;
  }

 private:
  // After the snapshot: stream the archive from it.
  void Start(Result<std::unique_ptr<ArchiveChunks>> archive) {
    if (!archive.ok()) {
      Finish(Failed(archive.status()));
      return;
    }
    archive_ = std::move(archive).value();
    AuditLog(*who_, "export_map", AuditBox(), archive_->version(), peer_);
    SendNext();
  }

  static grpc::Status Failed(const Status& s) {
    const grpc::StatusCode code = s.code() == Status::Code::kDataLoss
                                      ? grpc::StatusCode::DATA_LOSS
                                      : grpc::StatusCode::UNAVAILABLE;
    return {code, "map not exported: " + s.message()};
  }

  // Sends the archive's next chunk (or ends the call once it is complete).
  void SendNext() {
    Result<std::string> bytes = archive_->Next(ctx_.limits.region_chunk_bytes);
    if (!bytes.ok()) {
      Finish(Failed(bytes.status()));
      return;
    }
    if (bytes->empty() && sent_any_) {
      Finish(grpc::Status::OK);
      return;
    }
    chunk_.Clear();
    chunk_.set_data(std::move(bytes).value());
    if (!sent_any_) chunk_.set_map_version(archive_->version());
    sent_any_ = true;
    if (archive_->complete()) {
      chunk_.set_last(true);
      chunk_.set_tiles(archive_->tiles());
      spdlog::info(
          "event=export_map version={} region={} tiles={} bytes={} seconds={:.3f}",
          archive_->version(), box_.has_value(), archive_->tiles(), archive_->bytes(),
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    }
    stalled_.WriteStarted();
    StartWrite(&chunk_);
  }

  std::string AuditBox() const {
    if (!box_) return "box_cells=all";
    return "box_cells=[" + std::to_string(box_->min.x) + "," + std::to_string(box_->min.y) +
           "]..[" + std::to_string(box_->max.x) + "," + std::to_string(box_->max.y) + "]";
  }

  ServiceContext& ctx_;
  const PrincipalRef who_;
  const std::string peer_;
  QueryPermit permit_;
  StalledWriteWatch stalled_;
  bool registered_ = false;
  std::optional<CellBox> box_;  // none: the whole map
  std::chrono::steady_clock::time_point start_;
  std::unique_ptr<ArchiveChunks> archive_;  // the snapshot's archive, being encoded
  bool sent_any_ = false;
  v1::ArchiveChunk chunk_;
};

}  // namespace

grpc::ServerWriteReactor<v1::ArchiveChunk>* StartExportMap(ServiceContext& ctx,
                                                           grpc::CallbackServerContext* call,
                                                           PrincipalRef who,
                                                           const v1::ExportRequest* request) {
  return new ExportStream(ctx, call, std::move(who), *request);
}

}  // namespace bgkmap
