#include "durability/archive_import.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "bgkmap/storage/map_archive.h"
#include "bgkmap/storage/tile_codec.h"

namespace bgkmap {
namespace {

constexpr std::string_view kSpoolPrefix = "import-";

std::string TileName(TileKey k) {
  return "tile (" + std::to_string(k.x) + ", " + std::to_string(k.y) + ")";
}

// Storage messages about the spool file name its path, which means nothing to the client and
// tells it about the server's file system: "<path>: " goes, any other mention becomes "the
// upload".
std::string WithoutPath(std::string message, const std::string& path) {
  const std::string prefix = path + ": ";
  if (message.starts_with(prefix)) message.erase(0, prefix.size());
  for (size_t at = message.find(path); !path.empty() && at != std::string::npos;
       at = message.find(path, at)) {
    message.replace(at, path.size(), "the upload");
  }
  return message;
}

// The first bytes of the file are the archive magic.
bool StartsLikeAnArchive(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::string head(storage::kMapArchiveMagic.size(), '\0');
  const ssize_t n = ::read(fd, head.data(), head.size());
  ::close(fd);
  return n == static_cast<ssize_t>(head.size()) && head == storage::kMapArchiveMagic;
}

// Every cell of the tile lies within the engine's cell range.
bool InRange(TileKey k, int tile_size) {
  auto ok = [&](int t) {
    const int64_t first = int64_t{t} * tile_size, last = first + tile_size - 1;
    return first >= -kMaxCellIndex && last <= kMaxCellIndex;
  };
  return ok(k.x) && ok(k.y);
}

// Weights, pseudo-counts, second moments, the plane's k*u^2, k*v^2 and own weight are sums of
// non-negative values; S and the other plane moments are any finite number. Returns the first local
// cell that breaks this, or -1.
int FirstImpossibleCell(const Tile& t) {
  for (int i = 0; i < t.cell_count(); ++i) {
    const double w = t.w()[i], s = t.s()[i], q = t.q()[i];
    const float a = t.a()[i], b = t.b()[i];
    if (!(w >= 0.0 && std::isfinite(w)) || !std::isfinite(s) || !(q >= 0.0 && std::isfinite(q)) ||
        !(a >= 0.0f && std::isfinite(a)) || !(b >= 0.0f && std::isfinite(b))) {
      return i;
    }
    for (int m = 0; t.has_plane() && m < Tile::kPlaneMoments; ++m) {
      const double x = t.plane(m)[i];
      const bool square = m == Tile::kSuu || m == Tile::kSvv || m == Tile::kOwnW;
      if (!std::isfinite(x) || (square && !(x >= 0.0))) return i;
    }
  }
  return -1;
}

}  // namespace

Result<std::unique_ptr<SpoolFile>> SpoolFile::Create(const std::string& dir) {
  // Messages name no path: they go to the client (the handler logs the directory).
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Status::IoError("cannot create the spool directory: " + ec.message());
  std::string name = dir + "/" + std::string(kSpoolPrefix) + "XXXXXX";
  const int fd = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd < 0)
    return Status::IoError(std::string("cannot create a spool file: ") + std::strerror(errno));
  return std::unique_ptr<SpoolFile>(new SpoolFile(name, fd));
}

SpoolFile::~SpoolFile() {
  if (fd_ >= 0) ::close(fd_);
  ::unlink(path_.c_str());
}

Status SpoolFile::Append(std::string_view bytes) {
  if (fd_ < 0) return Status::IoError("the spool file is closed");
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      return Status::IoError(std::string("cannot write the spool file: ") +
                             (errno == ENOSPC ? "disk full" : std::strerror(errno)));
    }
    bytes.remove_prefix(static_cast<size_t>(n));
    size_ += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

Status SpoolFile::Close() {
  if (fd_ < 0) return Status::Ok();
  const int rc = ::close(fd_);
  fd_ = -1;
  return rc == 0 ? Status::Ok() : Status::IoError("cannot close the spool file");
}

void RemoveStaleSpoolFiles(const std::string& dir) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.path().filename().string().starts_with(kSpoolPrefix)) {
      std::filesystem::remove(entry.path(), ec);
    }
  }
}

Status ReadVerifiedArchive(const std::string& path, const MapParams& params,
                           const Georeference& georeference, VerifiedArchive* out) {
  if (!StartsLikeAnArchive(path)) {
    return Status::InvalidArgument(
        "archive: the upload is not a bgkmap map archive (it does not start with " +
        std::string(storage::kMapArchiveMagic) + ")");
  }
  Result<std::unique_ptr<storage::MapArchiveReader>> reader = storage::MapArchiveReader::Open(path);
  if (!reader.ok()) {
    return Status::DataLoss("archive: " + WithoutPath(reader.status().message(), path));
  }
  out->metadata = (*reader)->metadata();
  std::string why;
  if (!params.StatisticsCompatibleWith(out->metadata.params, &why)) {
    return Status::FailedPrecondition(
        "archive: its map parameters are incompatible with the served map's: " + why +
        " (served vs archive); statistics of one cannot be added to the other");
  }
  if (Status s = storage::CheckGeoreferenceCompatible(georeference, out->metadata.georeference,
                                                      "served vs archive");
      !s.ok()) {
    return Status::FailedPrecondition("archive: its georeference is not the served map's: " +
                                      s.message());
  }
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> tiles;
  for (;;) {
    TileKey key;
    std::unique_ptr<Tile> tile;
    Result<bool> more = (*reader)->Next(&key, &tile);
    if (!more.ok()) {
      return Status::DataLoss("archive: " + WithoutPath(more.status().message(), path));
    }
    if (!*more) break;
    if (!InRange(key, params.tile_size)) {
      return Status::InvalidArgument("archive: " + TileName(key) + " lies beyond the map's range");
    }
    if (const int cell = FirstImpossibleCell(*tile); cell >= 0) {
      return Status::InvalidArgument("archive: " + TileName(key) + " cell " + std::to_string(cell) +
                                     " holds impossible statistics (negative or non-finite)");
    }
    if (storage::IsZeroTile(*tile)) continue;  // adds nothing
    tiles.emplace_back(key, std::move(tile));
  }
  std::sort(tiles.begin(), tiles.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 1; i < tiles.size(); ++i) {
    if (tiles[i].first == tiles[i - 1].first) {
      return Status::InvalidArgument("archive: " + TileName(tiles[i].first) + " appears twice");
    }
  }
  out->keys.clear();
  out->tiles.clear();
  out->known_cells = 0;
  for (auto& [key, tile] : tiles) {
    out->known_cells += static_cast<uint64_t>(tile->CountKnown());
    out->keys.push_back(key);
    out->tiles.push_back(std::move(tile));
  }
  return Status::Ok();
}

}  // namespace bgkmap
