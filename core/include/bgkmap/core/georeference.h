// Where the map frame sits in a coordinate reference system (docs/configuration.md): map point
// (x, y, z) is origin + (x, y, z) in `crs`, axes aligned. An empty crs: the frame is local.
// Part of the map's identity, like the parameters: a store and its archives keep the one they
// were given first, and a different one is refused rather than silently replaced
// (storage::CheckGeoreferenceCompatible).
#pragma once

#include <array>
#include <string>

namespace bgkmap {

struct Georeference {
  std::string crs;                           // any form GDAL reads: "EPSG:<code>", WKT, PROJ
  std::array<double, 3> origin = {0, 0, 0};  // easting, northing, height of map (0, 0, 0)

  bool empty() const { return crs.empty(); }
  bool operator==(const Georeference&) const = default;
};

}  // namespace bgkmap
