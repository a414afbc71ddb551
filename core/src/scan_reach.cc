#include "scan_reach.h"

#include <algorithm>
#include <functional>

#include "bgkmap/core/cell_shapes.h"
#include "bgkmap/core/grid.h"

namespace bgkmap::internal {
namespace {

// Appends the tiles containing at least one offset cell of `reach` around each observed cell.
// `reach(dx, dy)` must be a disk-like predicate (true at 0, monotone in |offset|) contained in
// the square of half-size `radius`, so testing the tile cell nearest to the centre suffices.
void CollectTiles(const GridGeometry& geo, const std::vector<ObservedCell>& cells, int radius,
                  const std::function<bool(int, int)>& reach, std::vector<TileKey>& out) {
  for (const ObservedCell& oc : cells) {
    const CellIndex c = oc.cell;
    const TileKey lo = geo.TileOf({c.x - radius, c.y - radius});
    const TileKey hi = geo.TileOf({c.x + radius, c.y + radius});
    if (lo == hi) {
      if (out.empty() || out.back() != lo) out.push_back(lo);
      continue;
    }
    for (int ty = lo.y; ty <= hi.y; ++ty) {
      for (int tx = lo.x; tx <= hi.x; ++tx) {
        const CellBox box = geo.TileBox({tx, ty});
        const int dx = std::clamp(c.x, box.min.x, box.max.x) - c.x;
        const int dy = std::clamp(c.y, box.min.y, box.max.y) - c.y;
        if (reach(dx, dy)) out.push_back({tx, ty});
      }
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

}  // namespace

void ComputeScanTiles(const MapParams& p, PreparedScan& scan) {
  const GridGeometry geo(p.resolution, p.tile_size);
  const int kernel_radius = static_cast<int>(std::ceil(p.kernel_length / p.resolution));
  const int robot_radius = static_cast<int>(std::ceil(p.robot_radius / p.resolution));

  // Writes: the kernel support of every observed cell (the observed cell alone for baseline).
  std::vector<TileKey> writes;
  if (p.method == Method::kBaseline) {
    CollectTiles(
        geo, scan.cells, 0, [](int, int) { return true; }, writes);
  } else {
    CollectTiles(
        geo, scan.cells, kernel_radius,
        [&](int dx, int dy) { return InKernelSupport(dx, dy, p.resolution, p.kernel_length); },
        writes);
  }

  // The robot's footprint: its cells' own tiles.
  if (!scan.footprint_cells.empty()) {
    for (const CellIndex& c : scan.footprint_cells) writes.push_back(geo.TileOf(c));
    std::sort(writes.begin(), writes.end());
    writes.erase(std::unique(writes.begin(), writes.end()), writes.end());
  }

  // Reads: the robot-radius patch of every cell whose v is computed.
  std::vector<TileKey> reads;
  if (p.method == Method::kBgkTrav) {
    const double reach = kernel_radius + robot_radius + 1.0;  // Minkowski sum, generously
    CollectTiles(
        geo, scan.cells, kernel_radius + robot_radius + 1,
        [&](int dx, int dy) { return std::hypot(dx, dy) <= reach; }, reads);
  } else {
    CollectTiles(
        geo, scan.cells, robot_radius,
        [&](int dx, int dy) { return OffsetWithinRadius(dx, dy, p.robot_radius, p.resolution); },
        reads);
  }
  // Rays: the tiles of each ray's last clear_ray_length metres (its bounding box of tiles).
  std::vector<TileKey> rays;
  if (p.dynamics == Dynamics::kOn && scan.has_sensor && p.clear_ray_length > 0) {
    const double res = p.resolution;
    const double sx = scan.sensor_x / res, sy = scan.sensor_y / res;
    const double length = p.clear_ray_length / res;
    for (const ObservedCell& oc : scan.cells) {
      const double ex = oc.cell.x + 0.5, ey = oc.cell.y + 0.5;
      const double dist = std::hypot(sx - ex, sy - ey);
      const double f = dist > length ? length / dist : 1.0;
      // Slack each way: the cells the segment touches, and the kernel support around them
      // (a contradicted cell's neighbours re-learn their traversability).
      const int slack = kernel_radius + 1;
      const double fx = ex + (sx - ex) * f, fy = ey + (sy - ey) * f;
      const TileKey lo = geo.TileOf({static_cast<int>(std::floor(std::min(ex, fx))) - slack,
                                     static_cast<int>(std::floor(std::min(ey, fy))) - slack});
      const TileKey hi = geo.TileOf({static_cast<int>(std::floor(std::max(ex, fx))) + slack,
                                     static_cast<int>(std::floor(std::max(ey, fy))) + slack});
      if (lo == hi) {
        if (rays.empty() || rays.back() != lo) rays.push_back(lo);
        continue;
      }
      for (int ty = lo.y; ty <= hi.y; ++ty) {
        for (int tx = lo.x; tx <= hi.x; ++tx) rays.push_back({tx, ty});
      }
    }
    std::sort(rays.begin(), rays.end());
    rays.erase(std::unique(rays.begin(), rays.end()), rays.end());
  }
  std::vector<TileKey> clears;
  std::set_difference(rays.begin(), rays.end(), writes.begin(), writes.end(),
                      std::back_inserter(clears));
  std::vector<TileKey> changeable;
  std::merge(writes.begin(), writes.end(), clears.begin(), clears.end(),
             std::back_inserter(changeable));
  std::vector<TileKey> read_only;
  std::set_difference(reads.begin(), reads.end(), changeable.begin(), changeable.end(),
                      std::back_inserter(read_only));
  scan.write_tiles = std::move(writes);
  scan.read_tiles = std::move(read_only);
  scan.clear_tiles = std::move(clears);
}

}  // namespace bgkmap::internal
