// Which cells a shape covers: one rule for every disk and polygon in the map. A cell belongs to a
// shape when its centre lies inside it, boundary included; a disk's squared radius gets a
// relative tolerance of 1e-9, so a cell exactly at the radius (0.3 m at 0.1 m cells, where
// (0.3 / 0.1)^2 is 8.999999999999998 in doubles) is never lost to rounding. A shape that covers no
// cell centre covers the cell under its reference point, so a footprint is never empty.
#pragma once

#include <span>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap {

struct Point2 {
  double x = 0.0, y = 0.0;
};

inline constexpr double kRadiusTolerance = 1e-9;

// True iff the offset (dx, dy) lies within `radius`, boundary included (the tolerance above).
inline bool WithinRadius(double dx, double dy, double radius) {
  return dx * dx + dy * dy <= radius * radius * (1.0 + kRadiusTolerance);
}

// True iff the cell offset (dx, dy) lies within `radius` metres at `resolution`: the
// neighbourhood rule the engine's step/slope/roughness patch and its tile reach share.
inline bool OffsetWithinRadius(int dx, int dy, double radius, double resolution) {
  const double q = radius / resolution;
  return static_cast<double>(dx) * dx + static_cast<double>(dy) * dy <=
         q * q * (1.0 + kRadiusTolerance) + kRadiusTolerance;
}

// The offsets (dx, dy) with OffsetWithinRadius, in (dx, dy) order: the cells within `radius` of
// a cell's centre.
std::vector<CellIndex> DiskOffsets(double radius, double resolution);

// The cells whose centres lie within `radius` of `centre`, sorted by (x, y); the cell under
// `centre` when there is none. The caller bounds centre and radius so every index fits.
std::vector<CellIndex> CellsInDisk(const GridGeometry& grid, Point2 centre, double radius);

// The cells whose centres lie inside `polygon` (map frame, at least 3 vertices, even-odd rule),
// sorted by (x, y); the cell under `anchor` when there is none.
std::vector<CellIndex> CellsInPolygon(const GridGeometry& grid, std::span<const Point2> polygon,
                                      Point2 anchor);

}  // namespace bgkmap
