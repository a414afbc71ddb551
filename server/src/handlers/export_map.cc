// ExportMap (admin): the map, or the cells of a box, as one archive (storage/map_archive.h),
// streamed in chunks. The archive is a consistent snapshot at one map version V:
//   - with a store, a scheduler barrier checkpoints the map at V (so the store holds exactly
//     the map at V) and takes a RocksDB snapshot; the barrier ends and the tiles are read from
//     the snapshot while ingestion goes on. Tiles are never read from memory, which may hold
//     only part of the map;
//   - without a store, the barrier copies the region's tiles and they are streamed from the copy.
// A stored tile that fails its checksum fails the call with DATA_LOSS naming it: no archive is
// ever silently wrong.
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <climits>

#include "bgkmap/storage/map_archive.h"
#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/storage/tile_snapshot.h"
#include "handlers/handlers.h"
#include "request_checks.h"

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
      tile.w()[i] = 0.0;
      tile.s()[i] = 0.0;
      tile.a()[i] = 0.0f;
      tile.b()[i] = 0.0f;
    }
  }
  return !storage::IsZeroTile(tile);
}

class ExportStream final : public grpc::ServerWriteReactor<v1::ArchiveChunk> {
 public:
  ExportStream(ServiceContext& ctx, const v1::ExportRequest& request)
      : ctx_(ctx), permit_(ctx.queries, ctx.limits.max_concurrent_queries) {
    if (!permit_) {
      Finish(
          {grpc::StatusCode::RESOURCE_EXHAUSTED,
           "server.max_concurrent_queries = " + std::to_string(ctx.limits.max_concurrent_queries) +
               " queries are already running; retry later"});
      return;
    }
    if (ctx.sessions.draining()) {
      Finish({grpc::StatusCode::UNAVAILABLE, "server is shutting down"});
      return;
    }
    if (request.has_box()) {
      if (grpc::Status s = RegionCells(request.box(), "box", ctx.store.geometry(), 1, ctx.limits,
                                       /*limit_cells=*/false, &box_);
          !s.ok()) {
        Finish(s);
        return;
      }
      region_ = true;
      min_tile_ = ctx.store.geometry().TileOf(box_.min);
      max_tile_ = ctx.store.geometry().TileOf(box_.max);
    }
    start_ = std::chrono::steady_clock::now();
    ctx_.scheduler.SubmitBarrier([this](uint64_t applied) { TakeSnapshot(applied); });
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish({grpc::StatusCode::CANCELLED, "export stream cancelled"});
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] { SendNext(); });
  }

  void OnDone() override { delete this; }

 private:
  // At the barrier: no change in flight, every change up to `applied` is in the map.
  void TakeSnapshot(uint64_t applied) {
    metadata_.params = ctx_.store.params();
    metadata_.map_version = applied;
    metadata_.checkpoint_version = applied;
    grpc::Status status;
    if (ctx_.persistence != nullptr) {
      MapPersistence& p = *ctx_.persistence;
      if (Status s = p.Write(p.Capture(ctx_.store, applied)); !s.ok()) {
        status = {grpc::StatusCode::UNAVAILABLE,
                  "map not exported: cannot checkpoint it first: " + s.message()};
      } else {
        snapshot_ = p.store().NewSnapshot();
        metadata_.robot_sequences = p.RobotSequences();  // as logged up to `applied`
      }
    } else {
      keys_ = ctx_.store.ListTiles(min_tile_, max_tile_);
      copies_ = ctx_.store.CopyTiles(keys_);
    }
    boost::asio::post(ctx_.query_pool, [this, status] {
      if (!status.ok()) {
        Finish(status);
        return;
      }
      Start();
    });
  }

  void Start() {
    if (snapshot_ != nullptr) {
      Result<std::vector<storage::StoredTileInfo>> listed =
          snapshot_->ListTiles(min_tile_, max_tile_);
      if (!listed.ok()) {
        Finish(Failed(listed.status()));
        return;
      }
      for (const storage::StoredTileInfo& info : *listed) keys_.push_back(info.key);
    }
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
      if (next_ == keys_.size()) {
        if (Status s = writer_->Finish(); !s.ok()) {
          Finish(Failed(s));
          return;
        }
        complete_ = true;
        snapshot_.reset();
        break;
      }
      const TileKey key = keys_[next_];
      std::unique_ptr<Tile> tile;
      if (snapshot_ != nullptr) {
        Result<std::unique_ptr<Tile>> loaded = snapshot_->LoadTile(key);
        if (!loaded.ok()) {
          Finish(Failed(loaded.status()));
          return;
        }
        tile = std::move(*loaded);
      } else {
        tile = std::move(copies_[next_]);
      }
      ++next_;
      if (tile == nullptr || storage::IsZeroTile(*tile)) continue;
      if (region_ && !CropToBox(ctx_.store.geometry(), key, box_, *tile)) continue;
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
    StartWrite(&chunk_);
  }

  ServiceContext& ctx_;
  Permit permit_;
  bool region_ = false;
  CellBox box_;
  TileKey min_tile_{INT_MIN, INT_MIN}, max_tile_{INT_MAX, INT_MAX};
  std::chrono::steady_clock::time_point start_;
  storage::MapMetadata metadata_;
  std::unique_ptr<storage::TileSnapshot> snapshot_;  // with a store
  std::vector<TileKey> keys_;                        // to export, in key order
  std::vector<std::unique_ptr<Tile>> copies_;        // without a store: the tiles at the barrier
  size_t next_ = 0;
  std::unique_ptr<storage::MapArchiveWriter> writer_;
  std::string pending_;  // encoded, not yet sent
  bool complete_ = false;
  bool sent_any_ = false;
  v1::ArchiveChunk chunk_;
};

}  // namespace

grpc::ServerWriteReactor<v1::ArchiveChunk>* StartExportMap(ServiceContext& ctx,
                                                           const v1::ExportRequest* request) {
  return new ExportStream(ctx, *request);
}

}  // namespace bgkmap
