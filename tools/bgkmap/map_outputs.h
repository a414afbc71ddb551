// Writes a queried or built region where `--out` names it (output_file.h): a GeoTIFF with its QGIS
// style beside it, a PNG preview, ROS 2 map messages or a Nav2 map.
#pragma once

#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/ros_map_messages.h"

namespace bgkmap::cli {

// `path` must have passed OutputKindOf.
Status WriteMapOutput(const Raster& raster, const std::string& path, const io::GeoTiffOptions& tiff,
                      const io::RosMapOptions& ros);

}  // namespace bgkmap::cli
