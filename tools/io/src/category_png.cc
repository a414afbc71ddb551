#include "bgkmap/io/category_png.h"

#include <png.h>

#include <algorithm>
#include <cstring>

#include "bitmap_font.h"

namespace bgkmap::io {
namespace {

constexpr std::array<uint8_t, 3> kBackground = {24, 24, 24};
constexpr std::array<uint8_t, 3> kText = {235, 235, 235};
constexpr int kMargin = 6, kSwatch = 10, kLineHeight = 14;

}  // namespace

Status WriteCategoryPng(const std::string& path, int cols, int rows,
                        const std::vector<uint8_t>& classes,
                        const std::vector<CategoryClass>& legend, int scale) {
  if (cols <= 0 || rows <= 0 || scale <= 0 ||
      classes.size() != static_cast<size_t>(cols) * static_cast<size_t>(rows)) {
    return Status::InvalidArgument(path + ": class grid does not match its size");
  }
  for (uint8_t c : classes) {
    if (c >= legend.size()) return Status::InvalidArgument(path + ": class without a colour");
  }
  const int map_w = cols * scale, map_h = rows * scale;
  // The legend: as many entries per line as fit the width.
  int entry_w = 0;
  for (const CategoryClass& c : legend)
    entry_w = std::max(entry_w, kSwatch + 4 + internal::TextWidth(c.label, 1) + 2 * kMargin);
  const int width = std::max(map_w, entry_w);
  const int per_line = std::max(1, width / entry_w);
  const int lines = (static_cast<int>(legend.size()) + per_line - 1) / per_line;
  const int height = map_h + kMargin + lines * kLineHeight;
  std::vector<uint8_t> rgb(static_cast<size_t>(width) * height * 3);
  for (size_t i = 0; i < rgb.size(); i += 3) std::memcpy(&rgb[i], kBackground.data(), 3);
  auto put = [&](int x, int y, const std::array<uint8_t, 3>& c) {
    std::memcpy(&rgb[(static_cast<size_t>(y) * width + x) * 3], c.data(), 3);
  };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::array<uint8_t, 3>& colour = legend[classes[static_cast<size_t>(r) * cols + c]].rgb;
      for (int dy = 0; dy < scale; ++dy) {
        for (int dx = 0; dx < scale; ++dx) put(c * scale + dx, r * scale + dy, colour);
      }
    }
  }
  for (size_t i = 0; i < legend.size(); ++i) {
    const int x0 = static_cast<int>(i % per_line) * entry_w + kMargin;
    const int y0 = map_h + kMargin + static_cast<int>(i / per_line) * kLineHeight;
    for (int dy = 0; dy < kSwatch; ++dy) {
      for (int dx = 0; dx < kSwatch; ++dx) put(x0 + dx, y0 + dy, legend[i].rgb);
    }
    internal::DrawText(rgb, width, height, x0 + kSwatch + 4, y0 + 1, legend[i].label, 1, kText);
  }
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(width);
  png.height = static_cast<png_uint_32>(height);
  png.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&png, path.c_str(), 0, rgb.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    return Status::IoError(path + ": cannot write PNG: " + why);
  }
  return Status::Ok();
}

}  // namespace bgkmap::io
