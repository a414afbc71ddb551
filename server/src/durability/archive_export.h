// A map archive (storage/map_archive.h) written from the map's tiles at one version and handed
// out in chunks as it is encoded (ExportMap): tiles are read one at a time from a TilesAtVersion,
// so an export holds one tile and one chunk in memory, whatever the map's size.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "bgkmap/storage/map_archive.h"
#include "durability/durability.h"

namespace bgkmap {

class ArchiveExport {
 public:
  // The archive of `tiles` with `metadata` (its map_version is the export's version). With a
  // `box`, only its cells: tiles are cut to it, and a tile left empty is skipped.
  static Result<std::unique_ptr<ArchiveExport>> Start(std::unique_ptr<TilesAtVersion> tiles,
                                                      const storage::MapMetadata& metadata,
                                                      const GridGeometry& geometry,
                                                      const std::optional<CellBox>& box);
  ArchiveExport(const ArchiveExport&) = delete;
  ArchiveExport& operator=(const ArchiveExport&) = delete;

  // The next `max_bytes` bytes (fewer only for the last ones; none once complete). DataLoss
  // naming a stored tile that fails its checksum; the writer's error otherwise.
  Result<std::string> Next(size_t max_bytes);
  bool complete() const { return finished_ && pending_.empty(); }
  uint64_t version() const { return version_; }
  uint64_t tiles() const { return writer_->tiles(); }
  uint64_t bytes() const { return writer_->bytes(); }

 private:
  ArchiveExport(std::unique_ptr<TilesAtVersion> tiles, uint64_t version,
                const GridGeometry& geometry, const std::optional<CellBox>& box)
      : tiles_(std::move(tiles)), version_(version), geometry_(geometry), box_(box) {}
  // Encodes the next tile into pending_ (or the trailer, after the last one).
  Status EncodeNext();

  std::unique_ptr<TilesAtVersion> tiles_;  // released once every tile is encoded
  const uint64_t version_;
  const GridGeometry geometry_;
  const std::optional<CellBox> box_;
  std::unique_ptr<storage::MapArchiveWriter> writer_;
  size_t next_ = 0;
  std::string pending_;  // encoded, not yet handed out
  bool finished_ = false;
};

}  // namespace bgkmap
