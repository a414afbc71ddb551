// The cells a lidar ray passes over, walked backwards from its return toward the sensor: the
// free-space evidence of docs/semantics.md ("Dynamics"). Pure geometry in cell units.
#pragma once

#include <cmath>
#include <utility>

#include "bgkmap/core/grid.h"

namespace bgkmap::internal {

// Walks the horizontal segment from the centre of cell `end` toward the point (sx, sy) (cell
// units: metres / resolution) for at most `length` cells of distance, visiting every cell it
// crosses after `end` in order (Amanatides-Woo traversal). Calls visit(cell, t) with t the
// distance from the start to the middle of the segment's part inside that cell.
// `dist` is std::hypot(sx - (end.x + 0.5), sy - (end.y + 0.5)), for a caller that has it.
template <typename Visit>
void WalkRayBack(CellIndex end, double sx, double sy, double length, double dist, Visit&& visit) {
  const double x0 = end.x + 0.5, y0 = end.y + 0.5;
  const double dx = sx - x0, dy = sy - y0;
  if (!(dist > 0.0)) return;
  const double limit = std::min(length, dist);
  const double ux = dx / dist, uy = dy / dist;
  const int step_x = ux > 0 ? 1 : -1, step_y = uy > 0 ? 1 : -1;
  // Distance along the ray to the first vertical / horizontal cell boundary, and between them.
  const double delta_x = ux != 0 ? 1.0 / std::abs(ux) : INFINITY;
  const double delta_y = uy != 0 ? 1.0 / std::abs(uy) : INFINITY;
  double next_x = delta_x * 0.5, next_y = delta_y * 0.5;  // from a cell centre
  CellIndex c = end;
  double t_enter = std::min(next_x, next_y);
  while (t_enter < limit) {
    if (next_x < next_y) {
      c.x += step_x;
      next_x += delta_x;
    } else {
      c.y += step_y;
      next_y += delta_y;
    }
    const double t_exit = std::min({next_x, next_y, limit});
    visit(c, 0.5 * (t_enter + t_exit));
    t_enter = std::min(next_x, next_y);
  }
}

template <typename Visit>
void WalkRayBack(CellIndex end, double sx, double sy, double length, Visit&& visit) {
  const double dist = std::hypot(sx - (end.x + 0.5), sy - (end.y + 0.5));
  WalkRayBack(end, sx, sy, length, dist, std::forward<Visit>(visit));
}

// A walked cell's tile and its place in it, followed one step at a time as a walk moves (every
// step changes x or y by one), without the divisions of GridGeometry::TileOf and LocalIndex.
struct TileCursor {
  explicit TileCursor(int tile_size) : T(tile_size) {}

  void Reset(CellIndex c) {
    cell = c;
    key = {FloorDiv(c.x, T), FloorDiv(c.y, T)};
    lx = FloorMod(c.x, T);
    ly = FloorMod(c.y, T);
  }
  // c is a neighbour of the current cell (4-connected).
  void MoveTo(CellIndex c) {
    if (c.x != cell.x) Step(c.x - cell.x, lx, key.x);
    if (c.y != cell.y) Step(c.y - cell.y, ly, key.y);
    cell = c;
  }
  int index() const { return ly * T + lx; }  // GridGeometry::LocalIndex

  const int T;
  CellIndex cell;
  TileKey key;
  int lx = 0, ly = 0;

 private:
  void Step(int d, int& local, int& tile) const {
    local += d;
    if (local == T) {
      local = 0;
      ++tile;
    } else if (local < 0) {
      local = T - 1;
      --tile;
    }
  }
};

}  // namespace bgkmap::internal
