// QueryRegion: a region raster streamed as bands of rows, so any size fits under the gRPC
// message limit. The region is read atomically first (tiles held shared, in short table-lock
// bands), then streamed without holding any lock, so a slow reader never blocks ingestion.
#include <boost/asio/post.hpp>
#include <cstdint>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

constexpr uint32_t kMaxStride = 4096;

class RegionStream final : public grpc::ServerWriteReactor<v1::RegionChunk> {
 public:
  RegionStream(ServiceContext& ctx, grpc::CallbackServerContext* call, const Principal& who,
               const v1::RegionRequest& request)
      : ctx_(ctx), permit_(ctx, who), stalled_(call, ctx.limits.stalled_write_timeout_s) {
    if (!permit_) {
      Finish(permit_.refusal());
      return;
    }
    if (grpc::Status s = Parse(request); !s.ok()) {
      Finish(s);
      return;
    }
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
      Result<Raster> read = ctx_.map.ReadRegion(box_, layers_, stride_);
      if (!read.ok()) {
        Finish(ToGrpcStatus(read.status()));
        return;
      }
      raster_ = std::move(read).value();
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
    return grpc::Status::OK;
  }

  void WriteNext() {
    if (sent_header_ && next_row_ >= raster_.rows) {
      Finish(grpc::Status::OK);
      return;
    }
    chunk_.Clear();
    if (!sent_header_) {
      sent_header_ = true;
      v1::RasterHeader* h = chunk_.mutable_header();
      ToProto(raster_, h);
      h->set_map_version(version_);
    }
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
  uint64_t reserved_bytes_ = 0;
  v1::RegionChunk chunk_;
};

}  // namespace

grpc::ServerWriteReactor<v1::RegionChunk>* StartQueryRegion(ServiceContext& ctx,
                                                            grpc::CallbackServerContext* call,
                                                            PrincipalRef who,
                                                            const v1::RegionRequest* request) {
  return new RegionStream(ctx, call, *who, *request);
}

}  // namespace bgkmap
