#include "cluster/cluster_export.h"

#include <algorithm>

#include "bgkmap/storage/tile_codec.h"

namespace bgkmap::cluster {

ClusterArchive::ClusterArchive(std::unique_ptr<TerrainMap> tiles, uint64_t version,
                               const std::optional<CellBox>& box,
                               std::function<uint64_t(uint64_t)> tile_version)
    : tiles_(std::move(tiles)),
      version_(version),
      box_(box),
      tile_version_(std::move(tile_version)) {
  tiles_->ForEachTile([this](TileKey k, const Tile&) { keys_.push_back(k); });
  std::sort(keys_.begin(), keys_.end());
}

Result<std::unique_ptr<ArchiveChunks>> ClusterArchive::Start(
    std::unique_ptr<TerrainMap> tiles, const storage::MapMetadata& metadata,
    const std::optional<CellBox>& box, uint64_t log_sequence,
    std::function<uint64_t(uint64_t)> tile_version) {
  std::unique_ptr<ClusterArchive> out(
      new ClusterArchive(std::move(tiles), log_sequence, box, std::move(tile_version)));
  Result<std::unique_ptr<storage::MapArchiveWriter>> writer =
      storage::MapArchiveWriter::CreateForSink(
          [self = out.get()](std::string_view bytes) {
            self->pending_.append(bytes);
            return Status::Ok();
          },
          metadata);
  if (!writer.ok()) return writer.status();
  out->writer_ = std::move(writer).value();
  return std::unique_ptr<ArchiveChunks>(std::move(out));
}

Status ClusterArchive::EncodeNext() {
  if (next_ == keys_.size()) {
    finished_ = true;
    tiles_.reset();
    return writer_->Finish();
  }
  const TileKey key = keys_[next_++];
  const Tile* found = tiles_->FindTile(key);
  if (found == nullptr || storage::IsZeroTile(*found)) return Status::Ok();
  Tile tile = *found;
  tile.set_version(tile_version_(tile.version()));
  if (box_ && !storage::CropTileToBox(tiles_->geometry(), key, *box_, tile)) return Status::Ok();
  return writer_->Add(key, tile);
}

Result<std::string> ClusterArchive::Next(size_t max_bytes) {
  while (pending_.size() < max_bytes && !finished_) {
    if (Status s = EncodeNext(); !s.ok()) return s;
  }
  const size_t n = std::min(max_bytes, pending_.size());
  std::string out = pending_.substr(0, n);
  pending_.erase(0, n);
  return out;
}

}  // namespace bgkmap::cluster
