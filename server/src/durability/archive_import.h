// An uploaded map archive on its way into a map: spooled to a file as it arrives, then read and
// verified in full before anything changes (ImportMap; serving/archive_upload.h drives it).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/storage/map_metadata.h"

namespace bgkmap {

// A temporary file that is removed when the object goes away, whatever the outcome.
class SpoolFile {
 public:
  // A new, empty file "import-XXXXXX" in `dir` (created if missing). IoError if it cannot be;
  // the message names no path (it is meant for the client).
  static Result<std::unique_ptr<SpoolFile>> Create(const std::string& dir);
  ~SpoolFile();  // closes and removes the file
  SpoolFile(const SpoolFile&) = delete;
  SpoolFile& operator=(const SpoolFile&) = delete;

  Status Append(std::string_view bytes);
  // Flushes and closes the file for reading; Append() is refused after it.
  Status Close();
  const std::string& path() const { return path_; }
  uint64_t size() const { return size_; }

 private:
  SpoolFile(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
  std::string path_;
  int fd_;
  uint64_t size_ = 0;
};

// Removes spool files "import-*" that a crash left in `dir`.
void RemoveStaleSpoolFiles(const std::string& dir);

// A whole archive, verified, ready to be added into the map.
struct VerifiedArchive {
  storage::MapMetadata metadata;
  std::vector<TileKey> keys;                 // sorted, distinct
  std::vector<std::unique_ptr<Tile>> tiles;  // same order; none all-zero
  uint64_t known_cells = 0;                  // of the archive's tiles
};

// Reads and checks every byte of the archive at `path` against the map's `params`:
// InvalidArgument if it is not an archive, holds a tile twice, a tile beyond the map's range or
// an impossible statistic (negative or non-finite weight); DataLoss if it is damaged or
// truncated (checksums); FailedPrecondition naming the first incompatible parameter, or the
// georeference key if both the archive and the map (`georeference`) have one and they differ.
// Messages name the tile and never the spool file.
Status ReadVerifiedArchive(const std::string& path, const MapParams& params,
                           const Georeference& georeference, VerifiedArchive* out);

}  // namespace bgkmap
