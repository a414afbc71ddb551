// "City": a procedural street like the paper's structured environment (Sec. 3.1.1), 50 m wide
// and 210 m long (or longer: its pattern goes on, closed by a wall 15 m past either end). The road
// runs along +y at |x| < 6 m with a crown and a gentle grade; kerbs of 0.10-0.20 m lead to
// sidewalks (6-10.5 m) with kerb-cut ramps; buildings with alleys line both sides; parked cars,
// poles and trees whose canopies hang above the sensor. Analytic and deterministic, so scans and
// ground truth are reproducible.
#pragma once

#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

class CityWorld : public World {
 public:
  static constexpr double kLength = 210.0;  // the paper's metres of road, y = 0 .. kLength
  // A street of max(length, kLength) metres: the same for y <= kLength whatever the length.
  explicit CityWorld(double length = kLength) : length_(length > kLength ? length : kLength) {}
  double length() const { return length_; }
  static constexpr double kHalfWidth = 25.0;    // world spans |x| <= 25 m
  static constexpr double kRoadHalf = 6.0;      // kerb line
  static constexpr double kSidewalkEnd = 10.5;  // building line

  double SurfaceHeight(double x, double y) const override;
  bool InOverhang(double x, double y, double z) const override;
  double MaxHeight() const override { return 20.0; }

  // Height of the road centre at y (the grade), for placing a sensor above the road.
  static double RoadHeight(double y);
  // Kerb height at y, 0.10-0.20 m.
  static double KerbHeight(double y);

 private:
  double length_;
};

}  // namespace bgkmap::sim
