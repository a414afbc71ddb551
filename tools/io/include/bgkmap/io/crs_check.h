// The georeference rule for a map in metres, checked before any work: a GeoTIFF's coordinate
// system must be one GDAL knows, it must not be geographic (degrees: a metric map's coordinates
// would be written as nonsense angles), and a map frame that is local (a scan sequence's frame,
// the first scan's pose) is placed in a projected CRS only with an explicit origin (else the map
// would land at the CRS's false origin, e.g. on the equator, without a word).
#pragma once

#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct CrsUse {
  std::string crs;             // as the user gave it (EPSG:code, WKT or PROJ)
  std::string option;          // the option that gave it, for the message ("--crs")
  bool frame_is_local = true;  // the map frame's coordinates are not already the CRS's
  bool has_origin = false;     // an origin places the local frame in the CRS
};

// Ok, or InvalidArgument with one line naming the option, the CRS and what to do.
Status CheckCrsUse(const CrsUse& use);

}  // namespace bgkmap::io
