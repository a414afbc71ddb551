// ExportMap (admin): the map, or the cells of a box, as one archive (storage/map_archive.h),
// streamed in chunks. The archive is a consistent snapshot at one map version V
// (ServedMap::SubmitSnapshot: a checkpoint at a barrier, then the store's snapshot, or copies of
// the tiles for a map in memory), read while ingestion goes on. A stored tile that fails its
// checksum fails the call with DATA_LOSS naming it: no archive is ever silently wrong.
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <climits>
#include <cstdint>

#include "bgkmap/storage/map_archive.h"
#include "bgkmap/storage/tile_codec.h"
#include "rpc/handlers/handlers.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

// Zeroes the cells of `tile` (at `key`) outside `box`; false if nothing is left.
bool CropToBox(const GridGeometry& geometry, TileKey key, const CellBox& box, Tile& tile) {
  const CellIndex origin = geometry.TileOrigin(key);
  const int n = tile.tile_size();
  const bool inside = origin.x >= box.min.x && origin.y >= box.min.y &&
                      origin.x + n - 1 <= box.max.x && origin.y + n - 1 <= box.max.y;
  if (inside) return true;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const CellIndex cell{origin.x + x, origin.y + y};
      if (cell.x >= box.min.x && cell.x <= box.max.x && cell.y >= box.min.y &&
          cell.y <= box.max.y) {
        continue;
      }
      const int i = y * n + x;
      tile.ClearCell(i);
    }
  }
  return !storage::IsZeroTile(tile);
}

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
      if (grpc::Status s = RegionCells(request.box(), "box", ctx.map.geometry(), 1, ctx.limits,
                                       /*limit_cells=*/false, &box_);
          !s.ok()) {
        Finish(s);
        return;
      }
      region_ = true;
      min_tile_ = ctx.map.geometry().TileOf(box_.min);
      max_tile_ = ctx.map.geometry().TileOf(box_.max);
    }
    start_ = std::chrono::steady_clock::now();
    // A client that stops reading gives its slot and the store's snapshot back.
    registered_ = ctx_.sessions.Add(&stalled_, SessionRegistry::Kind::kStream, UINT32_MAX) ==
                  SessionRegistry::Admit::kOk;
    ctx_.map.SubmitSnapshot(min_tile_, max_tile_, [this](Result<MapSnapshot> snapshot) {
      auto shared = std::make_shared<Result<MapSnapshot>>(std::move(snapshot));
      boost::asio::post(ctx_.query_pool, [this, shared] { Start(std::move(*shared)); });
    });
  }

  void OnWriteDone(bool ok) override {
    stalled_.WriteDone();
    if (!ok) {
      tiles_.reset();  // the store's snapshot goes now, not when the call is done
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
  void Start(Result<MapSnapshot> snapshot) {
    if (!snapshot.ok()) {
      Finish(Failed(snapshot.status()));
      return;
    }
    AuditLog(*who_, "export_map", AuditBox(), snapshot->version, peer_);
    metadata_.params = ctx_.map.params();
    metadata_.georeference = ctx_.map.georeference();
    metadata_.map_version = snapshot->version;
    metadata_.checkpoint_version = snapshot->version;
    metadata_.robot_sequences = std::move(snapshot->robot_sequences);
    tiles_ = std::move(snapshot->tiles);
    Result<std::unique_ptr<storage::MapArchiveWriter>> writer =
        storage::MapArchiveWriter::CreateForSink(
            [this](std::string_view bytes) {
              pending_.append(bytes);
              return Status::Ok();
            },
            metadata_);
    if (!writer.ok()) {
      Finish(Failed(writer.status()));
      return;
    }
    writer_ = std::move(*writer);
    SendNext();
  }

  static grpc::Status Failed(const Status& s) {
    const grpc::StatusCode code = s.code() == Status::Code::kDataLoss
                                      ? grpc::StatusCode::DATA_LOSS
                                      : grpc::StatusCode::UNAVAILABLE;
    return {code, "map not exported: " + s.message()};
  }

  // Encodes tiles until a chunk is full (or the archive is complete) and sends it.
  void SendNext() {
    const size_t chunk_bytes = ctx_.limits.region_chunk_bytes;
    while (pending_.size() < chunk_bytes && !complete_) {
      if (next_ == tiles_->keys().size()) {
        if (Status s = writer_->Finish(); !s.ok()) {
          Finish(Failed(s));
          return;
        }
        complete_ = true;
        tiles_.reset();
        break;
      }
      const TileKey key = tiles_->keys()[next_];
      Result<std::unique_ptr<Tile>> loaded = tiles_->Take(next_);
      if (!loaded.ok()) {
        Finish(Failed(loaded.status()));
        return;
      }
      std::unique_ptr<Tile> tile = std::move(*loaded);
      ++next_;
      if (tile == nullptr || storage::IsZeroTile(*tile)) continue;
      if (region_ && !CropToBox(ctx_.map.geometry(), key, box_, *tile)) continue;
      if (Status s = writer_->Add(key, *tile); !s.ok()) {
        Finish(Failed(s));
        return;
      }
    }
    if (pending_.empty() && sent_any_) {
      Finish(grpc::Status::OK);
      return;
    }
    const size_t n = std::min(chunk_bytes, pending_.size());
    chunk_.Clear();
    chunk_.set_data(pending_.data(), n);
    pending_.erase(0, n);
    if (!sent_any_) chunk_.set_map_version(metadata_.map_version);
    sent_any_ = true;
    if (complete_ && pending_.empty()) {
      chunk_.set_last(true);
      chunk_.set_tiles(writer_->tiles());
      spdlog::info(
          "event=export_map version={} region={} tiles={} bytes={} seconds={:.3f}",
          metadata_.map_version, region_, writer_->tiles(), writer_->bytes(),
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    }
    stalled_.WriteStarted();
    StartWrite(&chunk_);
  }

  std::string AuditBox() const {
    if (!region_) return "box_cells=all";
    return "box_cells=[" + std::to_string(box_.min.x) + "," + std::to_string(box_.min.y) + "]..[" +
           std::to_string(box_.max.x) + "," + std::to_string(box_.max.y) + "]";
  }

  ServiceContext& ctx_;
  const PrincipalRef who_;
  const std::string peer_;
  QueryPermit permit_;
  StalledWriteWatch stalled_;
  bool registered_ = false;
  bool region_ = false;
  CellBox box_;
  TileKey min_tile_{INT_MIN, INT_MIN}, max_tile_{INT_MAX, INT_MAX};
  std::chrono::steady_clock::time_point start_;
  storage::MapMetadata metadata_;
  std::unique_ptr<TileSource> tiles_;  // the map's tiles at the snapshot, in key order
  size_t next_ = 0;
  std::unique_ptr<storage::MapArchiveWriter> writer_;
  std::string pending_;  // encoded, not yet sent
  bool complete_ = false;
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
