#include "bgkmap/storage/map_archive.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <utility>
#include <vector>

#include "bgkmap/storage/crc32c.h"
#include "bgkmap/storage/recovery.h"
#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

constexpr char kMagic[] = "BGKMAPA1";
constexpr size_t kMagicSize = 8;

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

MapArchiveWriter::MapArchiveWriter(std::string path, std::ofstream out)
    : path_(std::move(path)), out_(std::move(out)) {}

MapArchiveWriter::~MapArchiveWriter() {
  if (!finished_) {
    out_.close();
    std::remove((path_ + ".partial").c_str());
  }
}

Result<std::unique_ptr<MapArchiveWriter>> MapArchiveWriter::Create(const std::string& path,
                                                                   const MapMetadata& metadata) {
  std::ofstream out(path + ".partial", std::ios::binary | std::ios::trunc);
  if (!out) return Status::IoError("cannot create " + path + ".partial");
  std::unique_ptr<MapArchiveWriter> writer(new MapArchiveWriter(path, std::move(out)));
  std::string header(kMagic, kMagicSize);
  const std::string meta = EncodeMetadata(metadata);
  ByteWriter w(&header);
  w.PutFixed32(static_cast<uint32_t>(meta.size()));
  w.PutBytes(meta);
  if (Status s = writer->Write(header); !s.ok()) return s;
  return writer;
}

Status MapArchiveWriter::Write(const std::string& bytes) {
  crc_ = Crc32cExtend(crc_, bytes.data(), bytes.size());
  out_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return out_ ? Status::Ok() : Status::IoError("writing " + path_ + ".partial failed");
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
  ++tiles_;
  return Write(entry);
}

Status MapArchiveWriter::Finish() {
  std::string trailer;
  ByteWriter w(&trailer);
  w.PutU8('E');
  w.PutFixed64(tiles_);
  if (Status s = Write(trailer); !s.ok()) return s;
  std::string crc;
  ByteWriter(&crc).PutFixed32(crc_);
  out_.write(crc.data(), 4);
  out_.close();
  if (!out_) return Status::IoError("writing " + path_ + ".partial failed");
  if (Status s = SyncFile(path_ + ".partial"); !s.ok()) return s;
  if (std::rename((path_ + ".partial").c_str(), path_.c_str()) != 0) {
    return Status::IoError("cannot rename " + path_ + ".partial to " + path_);
  }
  finished_ = true;
  return Status::Ok();
}

bool MapArchiveReader::Read(size_t n, std::string* bytes) {
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
  std::string bytes;
  if (!reader->Read(kMagicSize + 4, &bytes) || bytes.compare(0, kMagicSize, kMagic) != 0) {
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
  Result<std::unique_ptr<Tile>> decoded = DecodeTile(encoded, metadata_.params.tile_size);
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
      InstallTile(map, key, *tile);  // bitwise, even for -0 cells
    } else {
      map.AddTile(key, *tile);
    }
  }
  report.tiles = tiles.size();
  const uint64_t top = std::max(map.version(), report.metadata.map_version);
  map.set_version(was_empty ? top : top + 1);
  return report;
}

}  // namespace bgkmap::storage
