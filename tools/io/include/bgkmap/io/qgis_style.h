// A QGIS style beside a GeoTIFF (`map.tif` -> `map.qml`, which QGIS loads as the layer's default
// style): the traversability band drawn green (0, flat and smooth) to red (1, not traversable),
// its NaN (unknown) cells transparent, instead of the first three float bands as RGB. Without a
// traversability band, the state band (traversable green, not traversable red, unknown 0 not
// drawn), else the first band as grey.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

// The .qml path of a GeoTIFF: its name with the extension replaced.
std::string QgisStylePath(const std::string& geotiff_path);

// Writes QgisStylePath(geotiff_path) for a file whose bands are `bands`, in order.
Status WriteQgisStyle(const std::vector<Layer>& bands, const std::string& geotiff_path);

}  // namespace bgkmap::io
