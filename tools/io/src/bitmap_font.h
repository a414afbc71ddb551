// A 5x7 bitmap font for the few labels of preview images (digits, upper-case letters, ". - : =").
// Internal to bgkmap_io: a font library would be a heavy dependency for a legend.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

namespace bgkmap::io::internal {

inline constexpr int kGlyphWidth = 5;
inline constexpr int kGlyphHeight = 7;

// Width in pixels of `text` drawn at integer `scale` (one blank column between glyphs).
int TextWidth(std::string_view text, int scale);

// Draws `text` (lower case is drawn as upper case, unknown characters as blanks) with its top-left
// corner at (x, y) into a packed RGB image of width x height pixels, clipping at the borders.
void DrawText(std::vector<uint8_t>& rgb, int width, int height, int x, int y, std::string_view text,
              int scale, std::array<uint8_t, 3> colour);

}  // namespace bgkmap::io::internal
