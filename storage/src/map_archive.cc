#include "bgkmap/storage/map_archive.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <utility>
#include <vector>

#include "bgkmap/storage/crc32c.h"
#include "bgkmap/storage/recovery.h"
#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

constexpr size_t kMagicSize = kMapArchiveMagic.size();

uint32_t Fixed32(const std::string& bytes, size_t at) {
  uint32_t v;
  std::memcpy(&v, bytes.data() + at, 4);
  return v;
}

Status SyncFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return Status::IoError("cannot reopen " + path + " to sync it");
  const int rc = ::fsync(fd);
  ::close(fd);
  return rc == 0 ? Status::Ok() : Status::IoError("fsync of " + path + " failed");
}

}  // namespace

struct MapArchiveWriter::File {
  std::string path;  // the final name; written as path + ".partial"
  std::ofstream out;
};

MapArchiveWriter::MapArchiveWriter(ArchiveSink sink, std::unique_ptr<File> file)
    : sink_(std::move(sink)), file_(std::move(file)) {}

MapArchiveWriter::~MapArchiveWriter() {
  if (file_ != nullptr && !finished_) {
    file_->out.close();
    std::remove((file_->path + ".partial").c_str());
  }
}

Result<std::unique_ptr<MapArchiveWriter>> MapArchiveWriter::Create(const std::string& path,
                                                                   const MapMetadata& metadata) {
  auto file = std::make_unique<File>();
  file->path = path;
  file->out.open(path + ".partial", std::ios::binary | std::ios::trunc);
  if (!file->out) return Status::IoError("cannot create " + path + ".partial");
  File* f = file.get();
  ArchiveSink sink = [f](std::string_view bytes) {
    f->out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return f->out ? Status::Ok() : Status::IoError("writing " + f->path + ".partial failed");
  };
  std::unique_ptr<MapArchiveWriter> writer(new MapArchiveWriter(std::move(sink), std::move(file)));
  if (Status s = writer->WriteHeader(metadata); !s.ok()) return s;
  return writer;
}

Result<std::unique_ptr<MapArchiveWriter>> MapArchiveWriter::CreateForSink(
    ArchiveSink sink, const MapMetadata& metadata) {
  std::unique_ptr<MapArchiveWriter> writer(new MapArchiveWriter(std::move(sink), nullptr));
  if (Status s = writer->WriteHeader(metadata); !s.ok()) return s;
  return writer;
}

Status MapArchiveWriter::WriteHeader(const MapMetadata& metadata) {
  std::string header(kMapArchiveMagic);
  const std::string meta = EncodeMetadata(metadata);
  ByteWriter w(&header);
  w.PutFixed32(static_cast<uint32_t>(meta.size()));
  w.PutBytes(meta);
  return Emit(header);
}

Status MapArchiveWriter::Emit(std::string_view bytes, bool checksummed) {
  if (!status_.ok()) return status_;
  if (checksummed) crc_ = Crc32cExtend(crc_, bytes.data(), bytes.size());
  status_ = sink_(bytes);
  if (status_.ok()) bytes_ += bytes.size();
  return status_;
}

Status MapArchiveWriter::Add(TileKey key, const Tile& tile) {
  const std::string encoded = EncodeTile(tile);
  std::string entry;
  ByteWriter w(&entry);
  w.PutU8('T');
  w.PutFixed32(static_cast<uint32_t>(key.x));
  w.PutFixed32(static_cast<uint32_t>(key.y));
  w.PutFixed32(static_cast<uint32_t>(encoded.size()));
  w.PutBytes(encoded);
  if (Status s = Emit(entry); !s.ok()) return s;
  ++tiles_;
  return Status::Ok();
}

Status MapArchiveWriter::Finish() {
  std::string trailer;
  ByteWriter w(&trailer);
  w.PutU8('E');
  w.PutFixed64(tiles_);
  if (Status s = Emit(trailer); !s.ok()) return s;
  std::string crc;
  ByteWriter(&crc).PutFixed32(crc_);
  if (Status s = Emit(crc, /*checksummed=*/false); !s.ok()) return s;
  if (file_ != nullptr) {
    const std::string partial = file_->path + ".partial";
    file_->out.close();
    if (!file_->out) return status_ = Status::IoError("writing " + partial + " failed");
    if (Status s = SyncFile(partial); !s.ok()) return status_ = s;
    if (std::rename(partial.c_str(), file_->path.c_str()) != 0) {
      return status_ = Status::IoError("cannot rename " + partial + " to " + file_->path);
    }
  }
  finished_ = true;
  return Status::Ok();
}

bool MapArchiveReader::Read(size_t n, std::string* bytes) {
  if (n > remaining_) return false;  // a damaged length must not allocate beyond the file
  remaining_ -= n;
  bytes->resize(n);
  in_.read(bytes->data(), static_cast<std::streamsize>(n));
  if (static_cast<size_t>(in_.gcount()) != n) return false;
  crc_ = Crc32cExtend(crc_, bytes->data(), n);
  return true;
}

Result<std::unique_ptr<MapArchiveReader>> MapArchiveReader::Open(const std::string& path) {
  std::unique_ptr<MapArchiveReader> reader(new MapArchiveReader());
  reader->in_.open(path, std::ios::binary);
  if (!reader->in_) return Status::IoError("cannot open " + path);
  reader->in_.seekg(0, std::ios::end);
  reader->remaining_ = static_cast<uint64_t>(std::max<std::streamoff>(reader->in_.tellg(), 0));
  reader->in_.seekg(0, std::ios::beg);
  std::string bytes;
  if (!reader->Read(kMagicSize + 4, &bytes) ||
      bytes.compare(0, kMagicSize, kMapArchiveMagic) != 0) {
    return Status::DataLoss(path + " is not a bgkmap map archive");
  }
  std::string meta;
  if (!reader->Read(Fixed32(bytes, kMagicSize), &meta)) {
    return Status::DataLoss(path + ": archive metadata is truncated");
  }
  Result<MapMetadata> metadata = DecodeMetadata(meta);
  if (!metadata.ok()) return Status::DataLoss(path + ": " + metadata.status().message());
  reader->metadata_ = std::move(*metadata);
  return reader;
}

Result<bool> MapArchiveReader::Next(TileKey* key, std::unique_ptr<Tile>* tile) {
  if (done_) return false;
  std::string bytes;
  if (!Read(1, &bytes)) return Status::DataLoss("map archive is truncated");
  if (bytes[0] == 'E') {
    std::string count;
    if (!Read(8, &count)) return Status::DataLoss("map archive trailer is truncated");
    const uint32_t computed = crc_;
    std::string stored(4, '\0');
    in_.read(stored.data(), 4);
    uint64_t n;
    std::memcpy(&n, count.data(), 8);
    if (in_.gcount() != 4 || Fixed32(stored, 0) != computed || n != tiles_) {
      return Status::DataLoss("map archive trailer does not verify (" + std::to_string(tiles_) +
                              " tiles read)");
    }
    if (remaining_ != 4) {
      return Status::DataLoss("map archive has " + std::to_string(remaining_ - 4) +
                              " unexpected bytes after its trailer");
    }
    done_ = true;
    return false;
  }
  if (bytes[0] != 'T' || !Read(12, &bytes)) {
    return Status::DataLoss("map archive entry " + std::to_string(tiles_) + " is malformed");
  }
  key->x = static_cast<int>(Fixed32(bytes, 0));
  key->y = static_cast<int>(Fixed32(bytes, 4));
  std::string encoded;
  if (!Read(Fixed32(bytes, 8), &encoded)) return Status::DataLoss("map archive is truncated");
  Result<std::unique_ptr<Tile>> decoded =
      DecodeTile(encoded, metadata_.params.tile_size, KeepsPlaneMoments(metadata_.params.method));
  if (!decoded.ok()) {
    return Status::DataLoss("map archive tile (" + std::to_string(key->x) + ", " +
                            std::to_string(key->y) + "): " + decoded.status().message());
  }
  *tile = std::move(*decoded);
  ++tiles_;
  return true;
}

Status ExportMap(const TerrainMap& map, const MapMetadata& metadata, const std::string& path) {
  Result<std::unique_ptr<MapArchiveWriter>> writer = MapArchiveWriter::Create(path, metadata);
  if (!writer.ok()) return writer.status();
  Status status;
  map.ForEachTile([&](TileKey key, const Tile& tile) {
    if (status.ok() && !IsZeroTile(tile)) status = (*writer)->Add(key, tile);
  });
  if (!status.ok()) return status;
  return (*writer)->Finish();
}

Result<ImportReport> ImportMap(const std::string& path, TerrainMap& map) {
  Result<std::unique_ptr<MapArchiveReader>> reader = MapArchiveReader::Open(path);
  if (!reader.ok()) return reader.status();
  ImportReport report;
  report.metadata = (*reader)->metadata();
  if (Status s = CheckParamsCompatible(map.params(), report.metadata.params); !s.ok()) {
    return Status::FailedPrecondition(path + ": " + s.message());
  }
  // Verify the whole archive before touching the map.
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> tiles;
  for (;;) {
    TileKey key;
    std::unique_ptr<Tile> tile;
    Result<bool> more = (*reader)->Next(&key, &tile);
    if (!more.ok()) return Status::DataLoss(path + ": " + more.status().message());
    if (!*more) break;
    tiles.emplace_back(key, std::move(tile));
  }
  const bool was_empty = map.tile_count() == 0;
  for (const auto& [key, tile] : tiles) {
    if (map.FindTile(key) == nullptr) {
      map.SetTile(key, *tile);  // bitwise, even for -0 cells
    } else {
      map.AddTile(key, *tile);
    }
  }
  report.tiles = tiles.size();
  const uint64_t top = std::max(map.version(), report.metadata.map_version);
  map.set_version(was_empty ? top : top + 1);
  return report;
}

bool CropTileToBox(const GridGeometry& geometry, TileKey key, const CellBox& box, Tile& tile) {
  const CellIndex origin = geometry.TileOrigin(key);
  const int n = tile.tile_size();
  const bool inside = origin.x >= box.min.x && origin.y >= box.min.y &&
                      origin.x + n - 1 <= box.max.x && origin.y + n - 1 <= box.max.y;
  if (inside) return true;
  tile.Unpack();  // ClearCell needs the dense form (a copy of a packed tile is packed)
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const CellIndex cell{origin.x + x, origin.y + y};
      if (cell.x >= box.min.x && cell.x <= box.max.x && cell.y >= box.min.y &&
          cell.y <= box.max.y) {
        continue;
      }
      tile.ClearCell(y * n + x);
    }
  }
  return !IsZeroTile(tile);
}

}  // namespace bgkmap::storage
