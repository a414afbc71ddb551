// Deterministic synthetic scans over analytic terrain, shared by the core tests.
#pragma once

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "bgkmap/core/scan.h"

namespace bgkmap::testing {

using Surface = std::function<double(double x, double y)>;

// Points sampled uniformly over the disk of `radius` around the sensor at `origin`, lying on
// `surface`, expressed in the sensor frame of an identity-rotation pose at `origin`.
inline std::vector<Point3f> SampleSurface(const Surface& surface, const Eigen::Vector3d& origin,
                                          double radius, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-radius, radius);
  std::vector<Point3f> pts;
  while (static_cast<int>(pts.size()) < count) {
    const double dx = u(rng), dy = u(rng);
    if (dx * dx + dy * dy > radius * radius) continue;
    const double x = origin.x() + dx, y = origin.y() + dy;
    pts.push_back({static_cast<float>(dx), static_cast<float>(dy),
                   static_cast<float>(surface(x, y) - origin.z())});
  }
  return pts;
}

// Map-frame points as a sensor at `origin` with an identity rotation (At(origin)) sees them.
inline std::vector<Point3f> InSensorFrame(const std::vector<Point3f>& map_frame,
                                          const Eigen::Vector3d& origin) {
  std::vector<Point3f> pts;
  pts.reserve(map_frame.size());
  for (const Point3f& q : map_frame) {
    pts.push_back({q.x - static_cast<float>(origin.x()), q.y - static_cast<float>(origin.y()),
                   q.z - static_cast<float>(origin.z())});
  }
  return pts;
}

inline Pose At(const Eigen::Vector3d& origin) {
  Pose p;
  p.translation = origin;
  return p;
}

// Gently rolling ground with a 0.2 m step along x = 2.
inline double RollingWithStep(double x, double y) {
  return 0.1 * std::sin(0.5 * x) + 0.05 * std::cos(0.7 * y) + (x > 2.0 ? 0.2 : 0.0);
}

}  // namespace bgkmap::testing
