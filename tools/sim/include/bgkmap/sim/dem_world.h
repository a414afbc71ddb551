// "Aerial": a real terrain (a DEM grid, bilinearly interpolated) with procedural rocks and
// ditches, like the paper's unstructured environment (Sec. 3.1.2). Rocks are half-ellipsoids,
// ditches parabolic trenches along segments; both are seeded, so worlds are reproducible.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/sim/max_mipmap.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

// A north-up height grid: values[r * cols + c], row 0 = north, NaN = no data.
struct HeightGrid {
  int64_t cols = 0;
  int64_t rows = 0;
  double x0 = 0;  // west edge of column 0, in the world frame
  double y0 = 0;  // south edge of the last row
  double cellsize = 1;
  std::vector<float> values;
};

// Fills every NaN cell from its valid neighbours, ring by ring inwards (each new value the mean of
// the valid 8-neighbours of the previous ring), so the surface is closed. A NODATA hole left open
// is a pit without walls: rays fall in and return from its sides below the terrain. Returns the
// number of cells filled; a grid without any valid cell is left as is.
int64_t FillNoData(HeightGrid& grid);

struct Rock {
  double x, y, radius, height;
};
struct Ditch {
  double x0, y0, x1, y1, width, depth;
};

struct ObstacleOptions {
  // Region the obstacles are scattered over (world frame).
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  int rocks = 150;  // radius 0.3-1.2 m, height 0.25-1.0 m
  int ditches = 6;  // 15-40 m long, 0.8-1.6 m wide, 0.3-0.7 m deep
  uint32_t seed = 7;
};

class DemWorld : public World {
 public:
  DemWorld(HeightGrid grid, const ObstacleOptions& obstacles);

  double SurfaceHeight(double x, double y) const override;
  double MaxHeight() const override { return max_height_; }
  double MaxHeightIn(double x0, double y0, double x1, double y1) const override;

  // The DEM alone (no rocks or ditches), NaN outside the data.
  double TerrainHeight(double x, double y) const;
  const std::vector<Rock>& rocks() const { return rocks_; }
  const std::vector<Ditch>& ditches() const { return ditches_; }

 private:
  void BuildBound();

  HeightGrid grid_;
  std::vector<Rock> rocks_;
  std::vector<Ditch> ditches_;
  double max_height_ = 0;
  // Per interpolation square (between 4 cell centres): the highest corner plus the tallest rock
  // touching it; ditches only lower the surface. -inf where a corner has no data.
  MaxMipmap bound_;
  // Rocks bucketed on a coarse grid so a height query looks at a few rocks only.
  static constexpr double kBucket = 4.0;
  double bx0_ = 0, by0_ = 0;
  int64_t bcols_ = 0, brows_ = 0;
  std::vector<std::vector<int>> buckets_;
};

}  // namespace bgkmap::sim
