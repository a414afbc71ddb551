#include "map_outputs.h"

#include "bgkmap/io/nav2_map_files.h"
#include "bgkmap/io/png_preview.h"
#include "bgkmap/io/qgis_style.h"
#include "output_file.h"

namespace bgkmap::cli {

Status WriteMapOutput(const Raster& raster, const std::string& path, const io::GeoTiffOptions& tiff,
                      const io::RosMapOptions& ros) {
  Result<OutputKind> kind = OutputKindOf(path, "--out");
  if (!kind.ok()) return kind.status();
  switch (*kind) {
    case OutputKind::kPng:
      return io::WritePreviewPng(raster, path);
    case OutputKind::kRosMcap:
      return io::WriteRosMapMcap(raster, path, ros);
    case OutputKind::kNav2Yaml:
      return io::WriteNav2Map(raster, path);
    case OutputKind::kGeoTiff:
      break;
  }
  if (Status s = io::WriteGeoTiff(raster, path, tiff); !s.ok()) return s;
  return io::WriteQgisStyle(raster.layers, path);
}

}  // namespace bgkmap::cli
