// What an output file's name asks for: `--out map.png` means a picture, not a GeoTIFF named .png.
#pragma once

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap::cli {

enum class OutputKind { kGeoTiff, kPng };

// .png: the PNG preview; an image format bgkmap does not write (.jpg, .jpeg, .gif, .bmp, .webp)
// is a usage error naming `option`; any other name (.tif, .tiff, none): a GeoTIFF.
inline Result<OutputKind> OutputKindOf(const std::string& path, const std::string& option) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".png") return OutputKind::kPng;
  for (const char* other : {".jpg", ".jpeg", ".gif", ".bmp", ".webp"}) {
    if (ext == other) {
      return Status::InvalidArgument(option + " " + path +
                                     ": bgkmap writes a GeoTIFF (.tif) or a PNG preview (.png)");
    }
  }
  return OutputKind::kGeoTiff;
}

}  // namespace bgkmap::cli
