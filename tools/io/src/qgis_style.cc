#include "bgkmap/io/qgis_style.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace bgkmap::io {
namespace {

struct Stop {
  double value;
  const char* color;
  const char* label;
};

// A singleband pseudocolor renderer of band `band` (1-based). INTERPOLATED ramps between stops;
// EXACT gives each listed value its colour and leaves other values (state 0) undrawn.
std::string Renderer(int band, const char* ramp, const std::vector<Stop>& stops) {
  std::string items;
  for (const Stop& s : stops) {
    items += fmt::format("          <item alpha=\"255\" value=\"{}\" label=\"{}\" color=\"{}\"/>\n",
                         s.value, s.label, s.color);
  }
  const double lo = stops.front().value, hi = stops.back().value;
  return fmt::format(
      "    <rasterrenderer type=\"singlebandpseudocolor\" band=\"{0}\" opacity=\"1\" "
      "alphaBand=\"-1\" classificationMin=\"{1}\" classificationMax=\"{2}\" nodataColor=\"\">\n"
      "      <rasterTransparency/>\n"
      "      <minMaxOrigin><limits>None</limits><extent>WholeRaster</extent></minMaxOrigin>\n"
      "      <rastershader>\n"
      "        <colorrampshader colorRampType=\"{3}\" classificationMode=\"1\" clip=\"1\" "
      "minimumValue=\"{1}\" maximumValue=\"{2}\">\n"
      "{4}"
      "        </colorrampshader>\n"
      "      </rastershader>\n"
      "    </rasterrenderer>\n",
      band, lo, hi, ramp, items);
}

std::string GreyRenderer(int band) {
  return fmt::format(
      "    <rasterrenderer type=\"singlebandgray\" grayBand=\"{}\" gradient=\"BlackToWhite\" "
      "opacity=\"1\" alphaBand=\"-1\">\n"
      "      <rasterTransparency/>\n"
      "      <minMaxOrigin><limits>MinMax</limits><extent>WholeRaster</extent></minMaxOrigin>\n"
      "    </rasterrenderer>\n",
      band);
}

}  // namespace

std::string QgisStylePath(const std::string& geotiff_path) {
  return std::filesystem::path(geotiff_path).replace_extension(".qml").string();
}

Status WriteQgisStyle(const std::vector<Layer>& bands, const std::string& geotiff_path) {
  const auto band_of = [&](Layer l) {
    const auto it = std::find(bands.begin(), bands.end(), l);
    return it == bands.end() ? 0 : static_cast<int>(it - bands.begin()) + 1;
  };
  std::string renderer;
  if (const int t = band_of(Layer::kTraversability)) {
    renderer = Renderer(t, "INTERPOLATED",
                        {{0.0, "#1a9641", "0 flat and smooth"},
                         {0.5, "#ffffbf", "0.5"},
                         {1.0, "#d7191c", "1 not traversable"}});
  } else if (const int s = band_of(Layer::kState)) {
    renderer = Renderer(s, "EXACT",
                        {{1.0, "#1a9641", "traversable"}, {2.0, "#d7191c", "not traversable"}});
  } else if (!bands.empty()) {
    renderer = GreyRenderer(1);
  }
  const std::string path = QgisStylePath(geotiff_path);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n"
      << "<!-- bgkmap: the layer's default style in QGIS (docs/semantics.md, the band contract) "
         "-->\n"
      << "<qgis version=\"3.22\" styleCategories=\"Symbology\">\n  <pipe>\n"
      << renderer << "  </pipe>\n  <blendMode>0</blendMode>\n</qgis>\n";
  out.close();
  if (!out) return Status::IoError(path + ": cannot write the QGIS style");
  return Status::Ok();
}

}  // namespace bgkmap::io
