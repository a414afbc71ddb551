#include "http/tile_png.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <iterator>
#include <stdexcept>

namespace bgkmap {
namespace {

struct Rgb {
  float r, g, b;
};

Rgb Mix(Rgb a, Rgb b, float t) {
  return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t};
}

// 0 (flat, smooth) green, 0.5 yellow, 1 (not traversable) red.
Rgb TraversabilityColor(float t) {
  t = std::clamp(t, 0.0f, 1.0f);
  constexpr Rgb kGreen{40, 170, 70}, kYellow{240, 210, 50}, kRed{205, 40, 40};
  return t < 0.5f ? Mix(kGreen, kYellow, t * 2) : Mix(kYellow, kRed, (t - 0.5f) * 2);
}

// A standard deviation over [0, full]: dark blue, cyan, white.
Rgb SpreadColor(float variance, float full) {
  const float u = std::clamp(std::sqrt(std::max(variance, 0.0f)) / full, 0.0f, 1.0f);
  constexpr Rgb kLow{20, 30, 90}, kMid{40, 170, 210}, kHigh{255, 255, 255};
  return u < 0.5f ? Mix(kLow, kMid, u * 2) : Mix(kMid, kHigh, (u - 0.5f) * 2);
}

// Lambertian shading under a light from the north-west, 45 degrees up, of the surface whose
// elevation around the pixel is `z` (NaN neighbours replaced by the centre).
float Hillshade(const std::vector<float>& z, int64_t cols, int64_t row, int64_t col,
                double pixel_metres) {
  const float c = z[static_cast<size_t>(row * cols + col)];
  auto at = [&](int64_t r, int64_t k) {
    const float v = z[static_cast<size_t>(r * cols + k)];
    return std::isnan(v) ? c : v;
  };
  constexpr double kExaggeration = 2.0;  // street-scale relief is small
  const double dzdx = (at(row, col + 1) - at(row, col - 1)) / (2 * pixel_metres) * kExaggeration;
  // Rows run north to south.
  const double dzdy = (at(row - 1, col) - at(row + 1, col)) / (2 * pixel_metres) * kExaggeration;
  const double norm = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1);
  constexpr double kLx = -0.5, kLy = 0.5, kLz = 0.70710678;  // azimuth 315, altitude 45
  const double shade = (-dzdx * kLx - dzdy * kLy + kLz) / norm;
  return static_cast<float>(std::clamp(shade, 0.0, 1.0));
}

// Traversable green, non-traversable red; unknown (0) is left transparent by the caller.
Rgb StateColor(float state) {
  return state == static_cast<float>(CellState::kTraversable) ? Rgb{40, 170, 70} : Rgb{205, 40, 40};
}

// The most telling reason first: evidence of an obstacle (dark red), observations that disagree
// (magenta), evidence too thin (blue), no traversability evidence (grey); traversable green.
Rgb BlockReasonColor(float reason) {
  const int r = static_cast<int>(reason);
  if (r & kBlockedMean) return {150, 20, 20};
  if (r & kBlockedDisagreement) return {200, 40, 200};
  if (r & kBlockedVariance) return {50, 90, 220};
  if (r & kBlockedNoValue) return {140, 140, 140};
  return {40, 170, 70};
}

void PngWrite(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::string*>(png_get_io_ptr(png));
  out->append(reinterpret_cast<const char*>(data), length);
}

void PngWarning(png_structp, png_const_charp) {}

}  // namespace

Result<Layer> ParseWebLayer(std::string_view name) {
  std::vector<Layer> choices(std::begin(kWebLayers), std::end(kWebLayers));
  std::sort(choices.begin(), choices.end());  // named in the engine's order
  std::string names;
  for (Layer l : choices) {
    if (LayerName(l) == name) return l;
    names += (names.empty() ? "" : ", ") + std::string(LayerName(l));
  }
  return Status::InvalidArgument("unknown layer '" + std::string(name) + "' (" + names + ")");
}

int WebMinZoom(uint64_t max_region_cells) {
  int z = 0;
  // A tile at zoom z - 1 reads (258 * 2^(1 - z))^2 cells, border included.
  while (z > -16) {
    const double side = (kWebTilePixels + 2) * std::ldexp(1.0, 1 - z);
    if (side * side > static_cast<double>(max_region_cells)) break;
    --z;
  }
  return z;
}

Result<WebTileCells> TileCells(int z, int64_t x, int64_t y, int min_zoom, double resolution,
                               double max_coordinate) {
  if (z < min_zoom || z > kWebMaxZoom) {
    return Status::OutOfRange("zoom " + std::to_string(z) + " is outside [" +
                              std::to_string(min_zoom) + ", " + std::to_string(kWebMaxZoom) + "]");
  }
  WebTileCells t;
  int64_t cells = kWebTilePixels;  // tile edge in cells
  if (z <= 0) {
    t.stride = 1 << -z;
    cells *= t.stride;
  } else {
    t.scale = 1 << z;
    cells /= t.scale;
  }
  // Cell indices stay well inside int32 for any tile within max_coordinate.
  const double limit = max_coordinate / resolution + static_cast<double>(cells);
  const double x0 = static_cast<double>(x) * static_cast<double>(cells);
  const double y0 = -static_cast<double>(y + 1) * static_cast<double>(cells);
  if (std::abs(x0) > limit || std::abs(y0) > limit) {
    return Status::OutOfRange("tile (" + std::to_string(x) + ", " + std::to_string(y) +
                              ") at zoom " + std::to_string(z) + " lies beyond max_coordinate");
  }
  const int64_t border = t.stride;  // one raster pixel
  t.box.min = {static_cast<int>(x * cells - border), static_cast<int>(-(y + 1) * cells - border)};
  t.box.max = {static_cast<int>((x + 1) * cells - 1 + border),
               static_cast<int>(-y * cells - 1 + border)};
  return t;
}

std::vector<uint8_t> RenderTile(const Raster& raster, Layer layer, const WebTileCells& cells) {
  constexpr int kN = kWebTilePixels;
  std::vector<uint8_t> rgba(static_cast<size_t>(kN) * kN * 4, 0);
  if (raster.data.empty()) return rgba;
  const std::vector<float>& v = raster.data[0];
  const int64_t cols = raster.cols;
  const double pixel_metres = raster.resolution;
  for (int py = 0; py < kN; ++py) {
    const int64_t row = 1 + py / cells.scale;
    for (int px = 0; px < kN; ++px) {
      const int64_t col = 1 + px / cells.scale;
      if (row >= raster.rows - 1 || col >= cols - 1) continue;
      const float value = v[static_cast<size_t>(row * cols + col)];
      if (std::isnan(value)) continue;
      Rgb c{};
      switch (layer) {
        case Layer::kElevation: {
          const float shade = Hillshade(v, cols, row, col, pixel_metres);
          const float g = 45 + 210 * shade;
          c = {g, g * 0.97f, g * 0.9f};
          break;
        }
        case Layer::kElevationVariance:
          c = SpreadColor(value, 0.5f);
          break;
        case Layer::kTraversability:
          c = TraversabilityColor(value);
          break;
        case Layer::kTraversabilityVariance:
          c = SpreadColor(value, 0.5f);
          break;
        case Layer::kState:
          if (value == static_cast<float>(CellState::kUnknown)) continue;
          c = StateColor(value);
          break;
        case Layer::kBlockReason:
          c = BlockReasonColor(value);
          break;
        case Layer::kDisagreement:  // metres: white at 0.3 m, twice the default step_crit
          c = SpreadColor(value * value, 0.3f);
          break;
        case Layer::kElevationWeight:  // not one of kWebLayers
          continue;
      }
      uint8_t* p = &rgba[(static_cast<size_t>(py) * kN + px) * 4];
      p[0] = static_cast<uint8_t>(std::lround(c.r));
      p[1] = static_cast<uint8_t>(std::lround(c.g));
      p[2] = static_cast<uint8_t>(std::lround(c.b));
      p[3] = 255;
    }
  }
  return rgba;
}

std::string EncodePng(const std::vector<uint8_t>& rgba, int width, int height) {
  std::string out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, PngWarning);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (info == nullptr || setjmp(png_jmpbuf(png)) != 0) {
    // libpng reports errors by longjmp: nothing with a destructor lives between here and there.
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error("png: cannot encode the tile");
  }
  png_set_write_fn(png, &out, PngWrite, nullptr);
  png_set_compression_level(png, 1);  // tiles are rendered per request: speed over size
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
               PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int r = 0; r < height; ++r) {
    png_write_row(png, rgba.data() + static_cast<size_t>(r) * width * 4);
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

}  // namespace bgkmap
