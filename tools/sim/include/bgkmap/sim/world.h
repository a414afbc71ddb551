// A world a simulated lidar can see: a 2.5D surface (terrain, kerbs, buildings as tall columns)
// plus optional overhanging volumes (tree canopies, bridges) that are not part of the ground.
#pragma once

#include <limits>

namespace bgkmap::sim {

class World {
 public:
  virtual ~World() = default;
  // Height of the top of the solid surface at (x, y), metres. NaN where there is nothing.
  virtual double SurfaceHeight(double x, double y) const = 0;
  // True if (x, y, z) lies inside an overhanging volume above the surface.
  virtual bool InOverhang(double /*x*/, double /*y*/, double /*z*/) const { return false; }
  // An upper bound of every surface and overhang: a ray climbing above it can never hit.
  virtual double MaxHeight() const { return std::numeric_limits<double>::infinity(); }
  // An upper bound of every surface and overhang over the rectangle [x0, x1] x [y0, y1]; -inf
  // where there is nothing. The ray caster skips the spans of a ray that stay above it, so a
  // world with a tight bound (DemWorld: a maximum mipmap) is cast much faster.
  virtual double MaxHeightIn(double /*x0*/, double /*y0*/, double /*x1*/, double /*y1*/) const {
    return MaxHeight();
  }
};

}  // namespace bgkmap::sim
