// Where a queried or built region goes, by the output's extension: `.mcap` ROS 2 map messages
// (io/ros_map_messages.h), `.yaml` Nav2 map_server's YAML + PGM (io/nav2_map_files.h), anything
// else a GeoTIFF.
#pragma once

#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/ros_map_messages.h"

namespace bgkmap::cli {

enum class MapOutputKind { kGeoTiff, kRosMcap, kNav2Yaml };

MapOutputKind MapOutputKindOf(const std::string& path);

Status WriteMapOutput(const Raster& raster, const std::string& path, const io::GeoTiffOptions& tiff,
                      const io::RosMapOptions& ros);

}  // namespace bgkmap::cli
