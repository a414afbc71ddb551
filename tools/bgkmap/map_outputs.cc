#include "map_outputs.h"

#include <filesystem>

#include "bgkmap/io/nav2_map_files.h"

namespace bgkmap::cli {

MapOutputKind MapOutputKindOf(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".mcap") return MapOutputKind::kRosMcap;
  if (ext == ".yaml" || ext == ".yml") return MapOutputKind::kNav2Yaml;
  return MapOutputKind::kGeoTiff;
}

Status WriteMapOutput(const Raster& raster, const std::string& path, const io::GeoTiffOptions& tiff,
                      const io::RosMapOptions& ros) {
  switch (MapOutputKindOf(path)) {
    case MapOutputKind::kRosMcap:
      return io::WriteRosMapMcap(raster, path, ros);
    case MapOutputKind::kNav2Yaml:
      return io::WriteNav2Map(raster, path);
    case MapOutputKind::kGeoTiff:
      break;
  }
  return io::WriteGeoTiff(raster, path, tiff);
}

}  // namespace bgkmap::cli
