// ExportMap on a shard: the archive of the tiles gathered from the partitions' owners exactly as
// of one log entry (an export's snapshot point, kExportSubject), encoded as it is read, tile by
// tile in key order like a single server's export, so the same map gives the same bytes.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/map_archive.h"
#include "serving/map_writes.h"

namespace bgkmap::cluster {

class ClusterArchive final : public ArchiveChunks {
 public:
  // The archive of `tiles` with `metadata`; with a `box`, only its cells (tiles cut to it, a tile
  // left empty skipped). `log_sequence`: the export's entry (version()); `tile_version` maps a
  // tile's version (a log sequence) to the one written.
  static Result<std::unique_ptr<ArchiveChunks>> Start(
      std::unique_ptr<TerrainMap> tiles, const storage::MapMetadata& metadata,
      const std::optional<CellBox>& box, uint64_t log_sequence,
      std::function<uint64_t(uint64_t)> tile_version);

  uint64_t version() const override { return version_; }
  Result<std::string> Next(size_t max_bytes) override;
  bool complete() const override { return finished_ && pending_.empty(); }
  uint64_t tiles() const override { return writer_->tiles(); }
  uint64_t bytes() const override { return writer_->bytes(); }

 private:
  ClusterArchive(std::unique_ptr<TerrainMap> tiles, uint64_t version,
                 const std::optional<CellBox>& box, std::function<uint64_t(uint64_t)> tile_version);
  Status EncodeNext();  // the next tile into pending_, or the trailer after the last

  std::unique_ptr<TerrainMap> tiles_;
  std::vector<TileKey> keys_;  // sorted
  const uint64_t version_;
  const std::optional<CellBox> box_;
  const std::function<uint64_t(uint64_t)> tile_version_;
  std::unique_ptr<storage::MapArchiveWriter> writer_;
  size_t next_ = 0;
  std::string pending_;
  bool finished_ = false;
};

}  // namespace bgkmap::cluster
