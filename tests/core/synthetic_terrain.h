// Deterministic synthetic scans over analytic terrain, shared by the core tests.
#pragma once

#include <cmath>
#include <functional>
#include <optional>
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

// A box standing in the lane |y| < 0.5 m, from x0 to x1 metres ahead, `height` tall.
struct LaneBox {
  float x0, x1, height;
};

// Map-frame returns of flat ground (z = 0) 3-8 m ahead of a sensor near the origin, |y| < 1.5 m,
// on a 0.1 m grid; with `box`, the box's top where it stands and no return from its shadow (the
// lane beyond it). The changing-world tests' scene: a vehicle in the lane ahead.
inline std::vector<Point3f> GroundAhead(std::optional<LaneBox> box = std::nullopt) {
  std::vector<Point3f> pts;
  for (int i = 0; i < 50; ++i) {
    for (int j = 0; j < 30; ++j) {
      const float x = 3.05f + 0.1f * i, y = -1.45f + 0.1f * j;
      const bool lane = y > -0.5f && y < 0.5f;
      if (box && lane && x > box->x0 && x < box->x1) {
        pts.push_back({x, y, box->height});
      } else if (!(box && lane && x > box->x1)) {
        pts.push_back({x, y, 0.0f});
      }
    }
  }
  return pts;
}

// Map-frame returns of flat ground only from `rows` rows of the same grid, the first at x_first
// (a scan that samples part of GroundAhead's ground and nothing else).
inline std::vector<Point3f> GroundStripAhead(float x_first, int rows) {
  std::vector<Point3f> pts;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < 30; ++j) pts.push_back({x_first + 0.1f * i, -1.45f + 0.1f * j, 0.0f});
  }
  return pts;
}

// Gently rolling ground with a 0.2 m step along x = 2.
inline double RollingWithStep(double x, double y) {
  return 0.1 * std::sin(0.5 * x) + 0.05 * std::cos(0.7 * y) + (x > 2.0 ? 0.2 : 0.0);
}

}  // namespace bgkmap::testing
