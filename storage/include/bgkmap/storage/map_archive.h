// A map in one portable file: metadata plus every tile, for export, archival and merging.
//
// Layout: "BGKMAPA1", fixed32 metadata length, metadata (EncodeMetadata), then per tile
// 'T', fixed32 x, fixed32 y, fixed32 length, tile encoding (its own CRC-32C); then 'E',
// fixed64 tile count, fixed32 CRC-32C of every byte before it. Little-endian throughout.
#pragma once

#include <cstdint>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/map_metadata.h"
#include "bgkmap/storage/tile_codec.h"

namespace bgkmap::storage {

// The first bytes of every archive.
inline constexpr std::string_view kMapArchiveMagic = "BGKMAPA1";

// Receives an archive's bytes in order. A non-OK status stops the writer: every later call
// returns it.
using ArchiveSink = std::function<Status(std::string_view bytes)>;

// Zeroes the cells of `tile` (at `key`) outside `box` (an export of a box); false if nothing is
// left (the tile is then not written).
bool CropTileToBox(const GridGeometry& geometry, TileKey key, const CellBox& box, Tile& tile);

// Writes one archive, to a file or to any byte sink (e.g. a network stream). The encoding is the
// same for both; only a file is synced and renamed into place.
class MapArchiveWriter {
 public:
  // Starts `path` (written as path + ".partial" and renamed by Finish, so a reader never sees
  // half an archive). IoError if the file cannot be created.
  static Result<std::unique_ptr<MapArchiveWriter>> Create(const std::string& path,
                                                          const MapMetadata& metadata);
  // Starts an archive whose bytes go to `sink`: the header at once, each tile on Add(), the
  // trailer on Finish(). The sink's error if it refuses the header.
  static Result<std::unique_ptr<MapArchiveWriter>> CreateForSink(ArchiveSink sink,
                                                                 const MapMetadata& metadata);
  ~MapArchiveWriter();  // a file without Finish(): removes the partial file

  Status Add(TileKey key, const Tile& tile);
  // Writes the trailer; a file is then synced and renamed into place.
  Status Finish();

  uint64_t tiles() const { return tiles_; }
  uint64_t bytes() const { return bytes_; }  // written so far

 private:
  struct File;
  MapArchiveWriter(ArchiveSink sink, std::unique_ptr<File> file);
  Status WriteHeader(const MapMetadata& metadata);
  // Passes `bytes` to the sink; `checksummed` bytes extend the trailer's CRC.
  Status Emit(std::string_view bytes, bool checksummed = true);

  ArchiveSink sink_;
  std::unique_ptr<File> file_;  // null for a sink
  Status status_;               // the first failure; sticky
  uint32_t crc_ = 0;
  uint64_t tiles_ = 0;
  uint64_t bytes_ = 0;
  bool finished_ = false;
};

class MapArchiveReader {
 public:
  // Reads the header and metadata. DataLoss if the file is not an archive or is damaged.
  static Result<std::unique_ptr<MapArchiveReader>> Open(const std::string& path);

  const MapMetadata& metadata() const { return metadata_; }

  // The next tile: true and the tile, or false at the verified end. DataLoss naming the tile or
  // the offset if anything fails its checksum or the file is truncated.
  Result<bool> Next(TileKey* key, std::unique_ptr<Tile>* tile);

 private:
  MapArchiveReader() = default;
  bool Read(size_t n, std::string* bytes);

  std::ifstream in_;
  uint64_t remaining_ = 0;  // bytes of the file not read yet: no length field reads past them
  MapMetadata metadata_;
  uint32_t crc_ = 0;
  uint64_t tiles_ = 0;
  bool done_ = false;
};

// Writes every tile of `map` (with `metadata`; its params should be the map's).
Status ExportMap(const TerrainMap& map, const MapMetadata& metadata, const std::string& path);

struct ImportReport {
  uint64_t tiles = 0;
  MapMetadata metadata;  // of the archive
};

// Adds the archive's statistics into `map` (TerrainMap::AddTile): importing into an empty map
// reproduces it, importing into a non-empty one merges (sums). FailedPrecondition naming the
// key if the archive's parameters are incompatible with the map's; nothing is added unless the
// whole archive verifies. The map version becomes max(map, archive) + 1 for a non-empty target.
Result<ImportReport> ImportMap(const std::string& path, TerrainMap& map);

}  // namespace bgkmap::storage
