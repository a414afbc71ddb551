#include "durability/archive_export.h"

#include <algorithm>

#include "bgkmap/storage/tile_codec.h"

namespace bgkmap {

Result<std::unique_ptr<ArchiveExport>> ArchiveExport::Start(std::unique_ptr<TilesAtVersion> tiles,
                                                            const storage::MapMetadata& metadata,
                                                            const GridGeometry& geometry,
                                                            const std::optional<CellBox>& box) {
  std::unique_ptr<ArchiveExport> out(
      new ArchiveExport(std::move(tiles), metadata.map_version, geometry, box));
  Result<std::unique_ptr<storage::MapArchiveWriter>> writer =
      storage::MapArchiveWriter::CreateForSink(
          [self = out.get()](std::string_view bytes) {
            self->pending_.append(bytes);
            return Status::Ok();
          },
          metadata);
  if (!writer.ok()) return writer.status();
  out->writer_ = std::move(writer).value();
  return out;
}

Status ArchiveExport::EncodeNext() {
  if (next_ == tiles_->keys().size()) {
    finished_ = true;
    tiles_.reset();  // the store's snapshot goes now, not when the export is dropped
    return writer_->Finish();
  }
  const TileKey key = tiles_->keys()[next_];
  Result<std::unique_ptr<Tile>> loaded = tiles_->Take(next_);
  if (!loaded.ok()) return loaded.status();
  ++next_;
  std::unique_ptr<Tile> tile = std::move(loaded).value();
  if (tile == nullptr || storage::IsZeroTile(*tile)) return Status::Ok();
  if (box_ && !storage::CropTileToBox(geometry_, key, *box_, *tile)) return Status::Ok();
  return writer_->Add(key, *tile);
}

Result<std::string> ArchiveExport::Next(size_t max_bytes) {
  while (pending_.size() < max_bytes && !finished_) {
    if (Status s = EncodeNext(); !s.ok()) return s;
  }
  const size_t n = std::min(max_bytes, pending_.size());
  std::string out = pending_.substr(0, n);
  pending_.erase(0, n);
  return out;
}

}  // namespace bgkmap
