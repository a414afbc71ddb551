// What an output file's name asks for: `--out map.png` means a picture, not a GeoTIFF named .png;
// `--out map.mcap` ROS 2 map messages; `--out map.yaml` Nav2 map_server's YAML + PGM.
#pragma once

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap::cli {

enum class OutputKind { kGeoTiff, kPng, kRosMcap, kNav2Yaml };

// .png: the PNG preview; .mcap: ROS 2 GridMap, OccupancyGrid and Nav2 Costmap
// (io/ros_map_messages.h); .yaml, .yml: Nav2 map_server's YAML + PGM (io/nav2_map_files.h); an
// image format bgkmap does not write (.jpg, .jpeg, .gif, .bmp, .webp) is a usage error naming
// `option`; any other name (.tif, .tiff, none): a GeoTIFF.
inline Result<OutputKind> OutputKindOf(const std::string& path, const std::string& option) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".png") return OutputKind::kPng;
  if (ext == ".mcap") return OutputKind::kRosMcap;
  if (ext == ".yaml" || ext == ".yml") return OutputKind::kNav2Yaml;
  for (const char* other : {".jpg", ".jpeg", ".gif", ".bmp", ".webp"}) {
    if (ext == other) {
      return Status::InvalidArgument(option + " " + path +
                                     ": bgkmap writes a GeoTIFF (.tif), a PNG preview (.png), ROS "
                                     "2 maps (.mcap) or a Nav2 map (.yaml)");
    }
  }
  return OutputKind::kGeoTiff;
}

}  // namespace bgkmap::cli
