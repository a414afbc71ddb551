// Integer grid geometry: cells, tiles, and boxes of cells. Cell (ix, iy) covers
// [ix*res, (ix+1)*res) x [iy*res, (iy+1)*res); its centre is ((ix+0.5)*res, (iy+0.5)*res).
#pragma once

#include <algorithm>
#include <cmath>
#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>

namespace bgkmap {

// Floor division for a positive divisor (C++ '/' truncates toward zero).
constexpr int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
constexpr int FloorMod(int a, int b) { return a - FloorDiv(a, b) * b; }

struct CellIndex {
  int x = 0;
  int y = 0;
  friend constexpr auto operator<=>(const CellIndex&, const CellIndex&) = default;
};

struct TileKey {
  int x = 0;
  int y = 0;
  friend constexpr auto operator<=>(const TileKey&, const TileKey&) = default;
};

struct TileKeyHash {
  size_t operator()(const TileKey& k) const {
    uint64_t v =
        (static_cast<uint64_t>(static_cast<uint32_t>(k.x)) << 32) | static_cast<uint32_t>(k.y);
    v ^= v >> 33;  // splitmix-style finaliser: neighbouring keys land far apart
    v *= 0xff51afd7ed558ccdULL;
    v ^= v >> 33;
    return static_cast<size_t>(v);
  }
};

// Inclusive box of cells [min.x, max.x] x [min.y, max.y]; empty when min > max.
struct CellBox {
  CellIndex min{1, 1};
  CellIndex max{0, 0};

  bool empty() const { return min.x > max.x || min.y > max.y; }
  int64_t width() const { return empty() ? 0 : int64_t{max.x} - min.x + 1; }
  int64_t height() const { return empty() ? 0 : int64_t{max.y} - min.y + 1; }
  int64_t cell_count() const { return width() * height(); }
  bool Contains(CellIndex c) const {
    return c.x >= min.x && c.x <= max.x && c.y >= min.y && c.y <= max.y;
  }
  void Extend(CellIndex c) {
    if (empty()) {
      min = max = c;
      return;
    }
    min = {std::min(min.x, c.x), std::min(min.y, c.y)};
    max = {std::max(max.x, c.x), std::max(max.y, c.y)};
  }
  CellBox Intersect(const CellBox& o) const {
    return {{std::max(min.x, o.min.x), std::max(min.y, o.min.y)},
            {std::min(max.x, o.max.x), std::min(max.y, o.max.y)}};
  }
  friend bool operator==(const CellBox&, const CellBox&) = default;
};

// Maps metric coordinates to cells and cells to tiles for one (resolution, tile_size).
class GridGeometry {
 public:
  GridGeometry(double resolution, int tile_size) : res_(resolution), tile_size_(tile_size) {}

  double resolution() const { return res_; }
  int tile_size() const { return tile_size_; }

  // floor(x / res) as a double, so callers can range-check before converting to int.
  double CellCoordinate(double x) const { return std::floor(x / res_); }
  CellIndex CellAt(double x, double y) const {
    return {static_cast<int>(CellCoordinate(x)), static_cast<int>(CellCoordinate(y))};
  }
  double CellCenterX(int ix) const { return (ix + 0.5) * res_; }
  double CellCenterY(int iy) const { return (iy + 0.5) * res_; }

  TileKey TileOf(CellIndex c) const {
    return {FloorDiv(c.x, tile_size_), FloorDiv(c.y, tile_size_)};
  }
  CellIndex TileOrigin(TileKey t) const { return {t.x * tile_size_, t.y * tile_size_}; }
  CellBox TileBox(TileKey t) const {
    CellIndex o = TileOrigin(t);
    return {o, {o.x + tile_size_ - 1, o.y + tile_size_ - 1}};
  }
  // A box of tile-local cells (0..tile_size-1) of tile `t` in map cells.
  CellBox LocalToMap(TileKey t, const CellBox& local) const {
    if (local.empty()) return {};
    const CellIndex o = TileOrigin(t);
    return {{o.x + local.min.x, o.y + local.min.y}, {o.x + local.max.x, o.y + local.max.y}};
  }
  // Row-major index of a cell inside its tile.
  int LocalIndex(CellIndex c) const {
    return FloorMod(c.y, tile_size_) * tile_size_ + FloorMod(c.x, tile_size_);
  }

  // Smallest cell box covering the closed metric rectangle [x0, x1] x [y0, y1]: every point of
  // it, edges included (a disk's or a footprint's bounding box).
  CellBox BoxCovering(double x0, double y0, double x1, double y1) const {
    return {CellAt(x0, y0), CellAt(x1, y1)};
  }

  // The cells [first, last] of the half-open interval [lo, hi) along one axis, at least one: an
  // upper edge on a cell border adds no cell. Edges within a micro-cell (1e-6 of a cell) of a
  // border snap to it, so 200 / 0.1 = 2000.0000000000002 and -10 / 0.1 = -100.00000000000001 add
  // no cell either. In int64, so a caller can bound the count before converting.
  struct CellRange {
    int64_t first, last;
  };
  CellRange CellsOfInterval(double lo, double hi) const {
    constexpr double kSnap = 1e-6;
    const auto first = static_cast<int64_t>(std::floor(lo / res_ + kSnap));
    const auto last = static_cast<int64_t>(std::ceil(hi / res_ - kSnap)) - 1;
    return {first, std::max(first, last)};
  }
  // The cells of the half-open region [x0, x1) x [y0, y1) (a region query's box, a scenario's
  // extent), by CellsOfInterval on each axis; the caller bounds it within +-kMaxCellIndex cells.
  CellBox CellsOfRegion(double x0, double y0, double x1, double y1) const {
    const CellRange x = CellsOfInterval(x0, x1), y = CellsOfInterval(y0, y1);
    return {{static_cast<int>(x.first), static_cast<int>(y.first)},
            {static_cast<int>(x.last), static_cast<int>(y.last)}};
  }

 private:
  double res_;
  int tile_size_;
};

}  // namespace bgkmap
