// The port's ArchiveUpload (serving/map_writes.h) for any map, the single server's and a cluster
// node's: the upload is spooled to a file, read back and checked in full against the map
// (durability/archive_import.h), and only then handed to the map's own change.
#pragma once

#include <functional>
#include <memory>
#include <span>
#include <string>

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "serving/map_writes.h"

namespace bgkmap {

// What an upload needs of the map it goes into.
struct UploadTarget {
  std::string directory;   // where to spool
  bool exclusive = false;  // only this server spools there: files a crash left may go
  MapParams params;
  std::function<Georeference()> georeference;
  // Before spooling `bytes` more: refused below the free-space reserve.
  std::function<Status(uint64_t bytes)> admit = nullptr;
  // Ties a map in a local frame to the archive's georeference (FailedPrecondition: another).
  std::function<Status(const Georeference&)> adopt_georeference;
  // Adds the checked tiles (sorted, distinct keys) as one change; `done` gets its version. The
  // spans stay valid until `done` runs.
  using Add = std::function<void(std::span<const TileKey>, std::span<const std::unique_ptr<Tile>>,
                                 std::function<void(Result<uint64_t>)> done)>;
  Add add;
};

// A new upload spooling in target.directory (created if missing). IoError naming no path (it is
// meant for the client) if the spool file cannot be created; the directory is logged.
Result<std::unique_ptr<ArchiveUpload>> StartArchiveUpload(UploadTarget target);

}  // namespace bgkmap
