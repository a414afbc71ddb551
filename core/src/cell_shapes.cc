#include "bgkmap/core/cell_shapes.h"

#include <algorithm>
#include <cmath>

namespace bgkmap {
namespace {

// Even-odd rule: a horizontal ray from (x, y) crosses the boundary an odd number of times.
bool InsidePolygon(std::span<const Point2> poly, double x, double y) {
  bool inside = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Point2 a = poly[i], b = poly[j];
    if ((a.y > y) != (b.y > y) && x < (b.x - a.x) * (y - a.y) / (b.y - a.y) + a.x) {
      inside = !inside;
    }
  }
  return inside;
}

// The cells of `box` (metres: x0, y0, x1, y1) whose centres pass `inside`, in (x, y) order, or
// the cell under `anchor`.
template <typename Inside>
std::vector<CellIndex> CellsWhere(const GridGeometry& g, const double (&box)[4], Point2 anchor,
                                  Inside inside) {
  const CellIndex lo = g.CellAt(box[0], box[1]);
  const CellIndex hi = g.CellAt(box[2], box[3]);
  std::vector<CellIndex> out;
  for (int ix = lo.x; ix <= hi.x; ++ix) {
    for (int iy = lo.y; iy <= hi.y; ++iy) {
      if (inside(g.CellCenterX(ix), g.CellCenterY(iy))) out.push_back({ix, iy});
    }
  }
  if (out.empty()) out.push_back(g.CellAt(anchor.x, anchor.y));
  return out;
}

}  // namespace

std::vector<CellIndex> DiskOffsets(double radius, double resolution) {
  const int r = static_cast<int>(std::ceil(radius / resolution));
  std::vector<CellIndex> out;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (OffsetWithinRadius(dx, dy, radius, resolution)) out.push_back({dx, dy});
    }
  }
  return out;
}

std::vector<CellIndex> CellsInDisk(const GridGeometry& grid, Point2 centre, double radius) {
  const double box[4] = {centre.x - radius, centre.y - radius, centre.x + radius,
                         centre.y + radius};
  return CellsWhere(grid, box, centre, [&](double x, double y) {
    return WithinRadius(x - centre.x, y - centre.y, radius);
  });
}

std::vector<CellIndex> CellsInPolygon(const GridGeometry& grid, std::span<const Point2> polygon,
                                      Point2 anchor) {
  double box[4] = {anchor.x, anchor.y, anchor.x, anchor.y};
  for (const Point2& v : polygon) {
    box[0] = std::min(box[0], v.x);
    box[1] = std::min(box[1], v.y);
    box[2] = std::max(box[2], v.x);
    box[3] = std::max(box[3], v.y);
  }
  return CellsWhere(grid, box, anchor,
                    [&](double x, double y) { return InsidePolygon(polygon, x, y); });
}

}  // namespace bgkmap
