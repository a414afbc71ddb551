// A small procedural street for benchmarks: gently rolling road, 0.15 m kerbs, sidewalks,
// parked cars and building walls. Deterministic and analytic, so scans are reproducible.
#pragma once

#include <cmath>

#include "bgkmap/sim/world.h"

namespace bgkmap::bench {

class StreetWorld : public sim::World {
 public:
  double SurfaceHeight(double x, double y) const override {
    double z = 0.05 * std::sin(0.13 * x) + 0.03 * std::cos(0.21 * y);
    const double ay = std::abs(y);
    if (ay > 5.0) z += 0.15;                                               // kerb onto the sidewalk
    if (ay > 9.0) z += 6.0 + 3.0 * (std::fmod(std::abs(x), 30.0) > 15.0);  // buildings
    // Parked cars every 12 m along both kerbs.
    const double cx = std::fmod(x + 1200.0, 12.0);
    if (ay > 3.2 && ay < 4.9 && cx > 2.0 && cx < 6.5) z += 1.4;
    return z;
  }
  bool InOverhang(double x, double y, double z) const override {
    // Tree canopies over the sidewalks, 3-6 m up.
    const double ty = std::abs(y) - 7.0, tx = std::fmod(x + 1200.0, 20.0) - 10.0;
    return tx * tx + ty * ty < 4.0 && z > 3.0 && z < 6.0;
  }
};

}  // namespace bgkmap::bench
