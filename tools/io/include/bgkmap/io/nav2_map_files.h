// Nav2 map_server's map files for a region: a YAML (image, mode trinary, resolution, origin,
// negate 0, occupied_thresh 0.65, free_thresh 0.25) and the PGM (P5) beside it, rows north to
// south as map_server reads them: 0 (black) lethal, 254 (white) free, 205 unknown. "Lethal" is
// the state layer's non-traversable, as in ros_map_messages.h.
#pragma once

#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

// Writes `yaml_path` and the PGM of the same name with the extension .pgm. Needs kState.
Status WriteNav2Map(const Raster& raster, const std::string& yaml_path);

}  // namespace bgkmap::io
