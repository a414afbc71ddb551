// QueryRegion: a region raster streamed as bands of rows, so any size fits under the gRPC
// message limit. The region is read atomically first (tiles held shared, in short table-lock
// bands), then streamed without holding any lock, so a slow reader never blocks ingestion.
// With since_version, only the tiles changed since are read and streamed, as patches
// (rpc/region_delta.h), or the whole region flagged as a resync when the delta cannot be exact.
#include <grpc/compression.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/region_delta.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

constexpr uint32_t kMaxStride = 4096;

class RegionStream final : public grpc::ServerWriteReactor<v1::RegionChunk> {
 public:
  RegionStream(ServiceContext& ctx, grpc::CallbackServerContext* call, const Principal& who,
               const v1::RegionRequest& request)
      : ctx_(ctx),
        permit_(ctx, who),
        stalled_(call, ctx.limits.stalled_write_timeout_s),
        received_(std::chrono::steady_clock::now()) {
    if (!permit_) {
      Finish(permit_.refusal());
      return;
    }
    if (grpc::Status s = Parse(request); !s.ok()) {
      Finish(s);
      return;
    }
    if (request.compress()) call->set_compression_algorithm(GRPC_COMPRESS_GZIP);
    // The raster is held in memory until streamed: bound the total over concurrent queries.
    const uint64_t pixels = static_cast<uint64_t>(box_.width() / stride_) *
                            static_cast<uint64_t>(box_.height() / stride_);
    reserved_bytes_ = pixels * layers_.size() * sizeof(float);
    if (!ctx_.region_bytes.TryAcquire(reserved_bytes_)) {
      reserved_bytes_ = 0;
      Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
              "region: " + std::to_string(pixels * layers_.size() * sizeof(float)) +
                  " bytes do not fit in server.max_region_bytes_in_flight = " +
                  std::to_string(ctx_.region_bytes.limit()) +
                  " with the regions being served now; retry later"});
      return;
    }
    // A client that stops reading gives its slot and its raster back.
    registered_ = ctx_.sessions.Add(&stalled_, SessionRegistry::Kind::kStream, UINT32_MAX) ==
                  SessionRegistry::Admit::kOk;
    boost::asio::post(ctx_.query_pool, [this] {
      version_ = ctx_.map.applied_version();
      if (delta_) {
        delta_->region = box_;
        delta_->layers = layers_;
        delta_->stride = stride_;
        Result<DeltaAnswer> delta = ReadRegionDelta(ctx_.map, *delta_, version_);
        if (!delta.ok()) {
          Finish(ToGrpcStatus(delta.status()));
          return;
        }
        if (delta->resync_reason.empty()) {
          patches_ = std::move(delta->patches);
          answer_ = v1::REGION_ANSWER_DELTA;
          ReadDone();
          WriteNext();
          return;
        }
        answer_ = v1::REGION_ANSWER_FULL_RESYNC;
        resync_reason_ = std::move(delta->resync_reason);
      }
      Result<Raster> read = ctx_.map.ReadRegion(box_, layers_, stride_);
      if (!read.ok()) {
        Finish(ToGrpcStatus(read.status()));
        return;
      }
      raster_ = std::move(read).value();
      ReadDone();
      const int64_t row_bytes =
          std::max<int64_t>(1, raster_.cols * static_cast<int64_t>(layers_.size()) * 4);
      rows_per_chunk_ =
          std::max<int64_t>(1, static_cast<int64_t>(ctx_.limits.region_chunk_bytes) / row_bytes);
      WriteNext();
    });
  }

  void OnWriteDone(bool ok) override {
    stalled_.WriteDone();
    if (!ok) {
      Finish({grpc::StatusCode::CANCELLED,
              stalled_.cancelled() ? "region stream cancelled: the client took no chunk for "
                                     "server.stalled_write_timeout_s"
                                   : "region stream cancelled"});
      return;
    }
    WriteNext();
  }

  void OnDone() override {
    if (registered_) ctx_.sessions.Remove(&stalled_);
    ctx_.region_bytes.Release(reserved_bytes_);
    delete this;
  }

 private:
  grpc::Status Parse(const v1::RegionRequest& request) {
    if (grpc::Status s = LayersFromProto(request.layers(), "layers", &layers_); !s.ok()) return s;
    stride_ = static_cast<int>(std::max<uint32_t>(request.stride(), 1));
    if (request.stride() > kMaxStride) {
      return {grpc::StatusCode::INVALID_ARGUMENT, "stride: " + std::to_string(request.stride()) +
                                                      " exceeds " + std::to_string(kMaxStride)};
    }
    if (grpc::Status s = RegionCells(request.box(), "box", ctx_.map.geometry(), stride_,
                                     ctx_.limits, /*limit_cells=*/true, &box_);
        !s.ok()) {
      return s;
    }
    // A chunk holds whole rows; one row must fit in a message.
    const uint64_t row_bytes = static_cast<uint64_t>(box_.width() / stride_) * layers_.size() * 4;
    if (row_bytes + 4096 > ctx_.limits.max_message_bytes) {
      return {grpc::StatusCode::INVALID_ARGUMENT,
              "box: one raster row takes " + std::to_string(row_bytes) +
                  " bytes, over server.max_message_bytes = " +
                  std::to_string(ctx_.limits.max_message_bytes)};
    }
    if (request.has_since_version()) {
      delta_ = DeltaQuery{};
      delta_->since = request.since_version();
      delta_->since_history_id = request.since_history_id();
    }
    return grpc::Status::OK;
  }

  void WriteHeader() {
    sent_header_ = true;
    v1::RasterHeader* h = chunk_.mutable_header();
    if (answer_ == v1::REGION_ANSWER_DELTA) {
      // The geometry without the pixels.
      ToProto(RasterGeometry(ctx_.map.geometry().resolution(), box_, layers_, stride_), h);
    } else {
      ToProto(raster_, h);
    }
    h->set_map_version(version_);
    h->set_answer(answer_);
    h->set_resync_reason(resync_reason_);
    h->set_history_id(ctx_.map.history_id());
  }

  // A delta: whole patches per chunk, about region_chunk_bytes each (at least one patch).
  void WriteNextPatches() {
    if (sent_header_ && next_patch_ >= patches_.size()) {
      FinishAnswered();
      return;
    }
    chunk_.Clear();
    if (!sent_header_) WriteHeader();
    size_t bytes = 0;
    while (next_patch_ < patches_.size() &&
           (bytes == 0 || bytes < ctx_.limits.region_chunk_bytes)) {
      bytes += patches_[next_patch_].ByteSizeLong();
      *chunk_.add_patches() = std::move(patches_[next_patch_++]);
    }
    stalled_.WriteStarted();
    StartWrite(&chunk_);
  }

  // The phases' timings (/metrics): the read once the answer is in memory, the transfer once
  // the client has taken every chunk.
  void ReadDone() {
    read_ = std::chrono::steady_clock::now();
    ctx_.latencies.of(RequestPhase::kRegionRead).Record(read_ - received_);
  }
  void FinishAnswered() {
    ctx_.latencies.of(RequestPhase::kRegionStream).Record(std::chrono::steady_clock::now() - read_);
    Finish(grpc::Status::OK);
  }

  void WriteNext() {
    if (answer_ == v1::REGION_ANSWER_DELTA) {
      WriteNextPatches();
      return;
    }
    if (sent_header_ && next_row_ >= raster_.rows) {
      FinishAnswered();
      return;
    }
    chunk_.Clear();
    if (!sent_header_) WriteHeader();
    const int64_t end = std::min(raster_.rows, next_row_ + rows_per_chunk_);
    chunk_.set_row_start(static_cast<uint32_t>(next_row_));
    chunk_.set_row_count(static_cast<uint32_t>(end - next_row_));
    AppendRows(raster_, next_row_, end, chunk_.mutable_layers());
    next_row_ = end;
    stalled_.WriteStarted();
    StartWrite(&chunk_);
  }

  ServiceContext& ctx_;
  QueryPermit permit_;
  StalledWriteWatch stalled_;
  bool registered_ = false;
  std::vector<Layer> layers_;
  int stride_ = 1;
  CellBox box_;
  uint64_t version_ = 0;
  Raster raster_;
  int64_t rows_per_chunk_ = 1;
  int64_t next_row_ = 0;
  bool sent_header_ = false;
  std::optional<DeltaQuery> delta_;
  v1::RegionAnswer answer_ = v1::REGION_ANSWER_FULL;
  std::string resync_reason_;
  std::vector<v1::TilePatch> patches_;
  size_t next_patch_ = 0;
  uint64_t reserved_bytes_ = 0;
  v1::RegionChunk chunk_;
  const std::chrono::steady_clock::time_point received_;
  std::chrono::steady_clock::time_point read_;
};

}  // namespace

grpc::ServerWriteReactor<v1::RegionChunk>* StartQueryRegion(ServiceContext& ctx,
                                                            grpc::CallbackServerContext* call,
                                                            PrincipalRef who,
                                                            const v1::RegionRequest* request) {
  return new RegionStream(ctx, call, *who, *request);
}

}  // namespace bgkmap
