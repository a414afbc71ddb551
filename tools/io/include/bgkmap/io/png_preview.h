// A quick-look PNG of a raster for people, not for analysis (use the GeoTIFF for that).
//   left:  elevation, colour ramp (2nd..98th percentile: green lowlands -> tan -> brown -> white)
//          shaded by a hillshade lit from the north-west; unknown cells dark grey.
//   right: traversability, green (0) -> yellow (0.5) -> red (1); unknown black; where a state
//          layer is present, non-traversable cells get a red tint.
// Below each panel a legend bar shows its colour ramp (low/0 on the left), labelled with the
// ramp's end values and the panel's name. A thin light separator divides the panels. Small rasters
// are upscaled (nearest) to at least ~600 px total width, big ones downscaled to at most 2048 px
// per panel edge; north is up.
#pragma once

#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct PreviewGeometry {
  int panel_width = 0;
  int panel_height = 0;
  int image_width = 0;   // 2 panels + separator
  int image_height = 0;  // panel + legend
};

// The image size WritePreviewPng produces for a raster of cols x rows pixels.
PreviewGeometry ComputePreviewGeometry(int64_t cols, int64_t rows);

// Needs an elevation or a traversability layer (a missing one is drawn as unknown).
Status WritePreviewPng(const Raster& raster, const std::string& path);

}  // namespace bgkmap::io
