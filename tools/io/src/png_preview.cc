#include "bgkmap/io/png_preview.h"

#include <fmt/format.h>
#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <vector>

#include "bitmap_font.h"

namespace bgkmap::io {
namespace {

using Rgb = std::array<uint8_t, 3>;

constexpr int kMinImageWidth = 600;
constexpr int kMaxPanelEdge = 2048;
constexpr int kSeparator = 4;
constexpr int kLegendGap = 4, kLegendBar = 12, kTextMargin = 4;
constexpr Rgb kTextColour = {235, 235, 235};

// Labels are drawn twice as large once a panel is wide enough for the longest one.
int TextScale(int panel_width) { return panel_width >= 450 ? 2 : 1; }
constexpr Rgb kSeparatorColour = {220, 220, 220};
constexpr Rgb kBackground = {24, 24, 24};
constexpr Rgb kUnknownElevation = {64, 64, 64};
constexpr Rgb kUnknownTraversability = {0, 0, 0};

struct Stop {
  double t;
  Rgb c;
};

Rgb Ramp(const std::vector<Stop>& stops, double t) {
  t = std::clamp(t, 0.0, 1.0);
  for (size_t i = 1; i < stops.size(); ++i) {
    if (t <= stops[i].t) {
      const double u = (t - stops[i - 1].t) / (stops[i].t - stops[i - 1].t);
      Rgb out;
      for (int k = 0; k < 3; ++k) {
        out[k] = static_cast<uint8_t>(
            std::lround(stops[i - 1].c[k] + u * (stops[i].c[k] - stops[i - 1].c[k])));
      }
      return out;
    }
  }
  return stops.back().c;
}

const std::vector<Stop>& ElevationStops() {
  static const std::vector<Stop> stops = {{0.0, {20, 110, 60}},
                                          {0.3, {120, 170, 80}},
                                          {0.55, {225, 205, 130}},
                                          {0.8, {160, 90, 40}},
                                          {1.0, {245, 245, 245}}};
  return stops;
}

const std::vector<Stop>& TraversabilityStops() {
  static const std::vector<Stop> stops = {
      {0.0, {0, 170, 0}}, {0.5, {235, 215, 0}}, {1.0, {215, 0, 0}}};
  return stops;
}

Rgb Scale(Rgb c, double f) {
  for (auto& v : c) v = static_cast<uint8_t>(std::clamp(std::lround(v * f), 0L, 255L));
  return c;
}

Rgb Blend(Rgb a, Rgb b, double w) {
  for (int k = 0; k < 3; ++k) a[k] = static_cast<uint8_t>(std::lround(a[k] + w * (b[k] - a[k])));
  return a;
}

// Robust colour range: the 2nd and 98th percentiles, so a few outliers don't flatten the ramp.
std::pair<double, double> ElevationRange(const std::vector<float>& z) {
  std::vector<float> finite;
  for (float v : z) {
    if (std::isfinite(v)) finite.push_back(v);
  }
  if (finite.empty()) return {0.0, 1.0};
  auto at = [&](double q) {
    auto it = finite.begin() + static_cast<ptrdiff_t>(q * (finite.size() - 1));
    std::nth_element(finite.begin(), it, finite.end());
    return static_cast<double>(*it);
  };
  const double lo = at(0.02), hi = at(0.98);
  return {lo, hi > lo ? hi : lo + 1.0};
}

// Lambertian hillshade in [0, 1] per raster pixel, light from azimuth 315 deg at 45 deg
// altitude. Gradients use central differences, one-sided next to unknown cells.
std::vector<float> Hillshade(const std::vector<float>& z, int64_t cols, int64_t rows, double res) {
  auto get = [&](int64_t c, int64_t r) {
    return (c < 0 || r < 0 || c >= cols || r >= rows) ? NAN : z[r * cols + c];
  };
  auto slope = [&](float minus, float centre, float plus) {
    if (std::isfinite(minus) && std::isfinite(plus)) return (plus - minus) / (2 * res);
    if (std::isfinite(plus)) return (plus - centre) / res;
    if (std::isfinite(minus)) return (centre - minus) / res;
    return 0.0;
  };
  const double alt = std::numbers::pi / 4;
  const double lx = -std::cos(alt) / std::sqrt(2.0), ly = std::cos(alt) / std::sqrt(2.0),
               lz = std::sin(alt);
  std::vector<float> shade(z.size(), 1.0f);
  for (int64_t r = 0; r < rows; ++r) {
    for (int64_t c = 0; c < cols; ++c) {
      const float h = get(c, r);
      if (!std::isfinite(h)) continue;
      const double dzdx = slope(get(c - 1, r), h, get(c + 1, r));
      const double dzdy = slope(get(c, r + 1), h, get(c, r - 1));  // row 0 is north
      const double n = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
      shade[r * cols + c] = static_cast<float>(std::max(0.0, (-dzdx * lx - dzdy * ly + lz) / n));
    }
  }
  return shade;
}

}  // namespace

PreviewGeometry ComputePreviewGeometry(int64_t cols, int64_t rows) {
  const int64_t longest = std::max(cols, rows);
  double s = 1.0;
  const int64_t min_panel = (kMinImageWidth - kSeparator + 1) / 2;
  if (cols < min_panel) s = static_cast<double>((min_panel + cols - 1) / cols);  // integer: crisp
  if (longest * s > kMaxPanelEdge) s = static_cast<double>(kMaxPanelEdge) / longest;
  PreviewGeometry g;
  g.panel_width = std::max(1, static_cast<int>(cols * s));
  g.panel_height = std::max(1, static_cast<int>(rows * s));
  g.image_width = 2 * g.panel_width + kSeparator;
  g.image_height = g.panel_height + kLegendGap + kLegendBar + 2 * kTextMargin +
                   internal::kGlyphHeight * TextScale(g.panel_width);
  return g;
}

Status WritePreviewPng(const Raster& raster, const std::string& path) {
  const int64_t cols = raster.cols, rows = raster.rows;
  if (cols <= 0 || rows <= 0) {
    return Status::InvalidArgument(
        fmt::format("{}: raster size {} x {} is empty", path, cols, rows));
  }
  auto layer = [&](Layer l) -> const std::vector<float>* {
    for (size_t i = 0; i < raster.layers.size() && i < raster.data.size(); ++i) {
      if (raster.layers[i] == l) {
        return static_cast<int64_t>(raster.data[i].size()) == rows * cols ? &raster.data[i]
                                                                          : nullptr;
      }
    }
    return nullptr;
  };
  const std::vector<float>* elevation = layer(Layer::kElevation);
  const std::vector<float>* trav = layer(Layer::kTraversability);
  const std::vector<float>* state = layer(Layer::kState);
  if (!elevation && !trav) {
    return Status::InvalidArgument(path +
                                   ": raster has no elevation or traversability layer "
                                   "of rows x cols values");
  }

  std::vector<float> shade;
  std::pair<double, double> range{0.0, 1.0};
  if (elevation) {
    shade = Hillshade(*elevation, cols, rows, raster.resolution > 0 ? raster.resolution : 1.0);
    range = ElevationRange(*elevation);
  }

  const PreviewGeometry g = ComputePreviewGeometry(cols, rows);
  std::vector<uint8_t> image(static_cast<size_t>(g.image_width) * g.image_height * 3);
  auto put = [&](int x, int y, Rgb c) {
    std::memcpy(&image[(static_cast<size_t>(y) * g.image_width + x) * 3], c.data(), 3);
  };
  for (int y = 0; y < g.image_height; ++y) {
    for (int x = 0; x < g.image_width; ++x) put(x, y, kBackground);
  }

  const int right = g.panel_width + kSeparator;
  for (int y = 0; y < g.panel_height; ++y) {
    const int64_t r = std::min<int64_t>(rows - 1, static_cast<int64_t>(y) * rows / g.panel_height);
    for (int x = 0; x < g.panel_width; ++x) {
      const int64_t c = std::min<int64_t>(cols - 1, static_cast<int64_t>(x) * cols / g.panel_width);
      const size_t i = static_cast<size_t>(r * cols + c);

      Rgb left = kUnknownElevation;
      if (elevation && std::isfinite((*elevation)[i])) {
        const double t = ((*elevation)[i] - range.first) / (range.second - range.first);
        left = Scale(Ramp(ElevationStops(), t), 0.25 + 0.9 * shade[i]);
      }
      put(x, y, left);

      Rgb rc = kUnknownTraversability;
      if (trav && std::isfinite((*trav)[i])) rc = Ramp(TraversabilityStops(), (*trav)[i]);
      if (state && (*state)[i] == static_cast<float>(CellState::kNonTraversable)) {
        rc = Blend(rc, {255, 0, 0}, 0.5);
      }
      put(right + x, y, rc);
    }
    for (int x = g.panel_width; x < right; ++x) put(x, y, kSeparatorColour);
  }

  // Legend bars: each panel's ramp from its low end (left) to its high end (right).
  const int bar_top = g.panel_height + kLegendGap;
  for (int y = bar_top; y < bar_top + kLegendBar; ++y) {
    for (int x = 0; x < g.panel_width; ++x) {
      const double t = g.panel_width > 1 ? static_cast<double>(x) / (g.panel_width - 1) : 0.0;
      put(x, y, Ramp(ElevationStops(), t));
      put(right + x, y, Ramp(TraversabilityStops(), t));
    }
  }

  // Labels under the bars: the ramp's end values at its ends, the panel's name between them
  // when it fits.
  const int scale = TextScale(g.panel_width);
  const int text_y = bar_top + kLegendBar + kTextMargin;
  auto label = [&](int x0, const std::string& lo, const std::string& name, const std::string& hi) {
    const int lo_w = internal::TextWidth(lo, scale), hi_w = internal::TextWidth(hi, scale);
    const int name_w = internal::TextWidth(name, scale), gap = 3 * internal::kGlyphWidth * scale;
    internal::DrawText(image, g.image_width, g.image_height, x0 + kTextMargin, text_y, lo, scale,
                       kTextColour);
    internal::DrawText(image, g.image_width, g.image_height,
                       x0 + g.panel_width - hi_w - kTextMargin, text_y, hi, scale, kTextColour);
    if (lo_w + name_w + hi_w + 2 * gap + 2 * kTextMargin <= g.panel_width) {
      internal::DrawText(image, g.image_width, g.image_height, x0 + (g.panel_width - name_w) / 2,
                         text_y, name, scale, kTextColour);
    }
  };
  if (elevation) {
    label(0, fmt::format("{:.1f} M", range.first), "ELEVATION",
          fmt::format("{:.1f} M", range.second));
  } else {
    label(0, "", "NO ELEVATION", "");
  }
  label(right, "0", state ? "TRAVERSABILITY  RED TINT = BLOCKED" : "TRAVERSABILITY", "1");

  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(g.image_width);
  png.height = static_cast<png_uint_32>(g.image_height);
  png.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&png, path.c_str(), 0, image.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    return Status::IoError(path + ": cannot write PNG: " + why);
  }
  return Status::Ok();
}

}  // namespace bgkmap::io
