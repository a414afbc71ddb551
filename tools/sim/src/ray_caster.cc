#include "bgkmap/sim/ray_caster.h"

#include <cmath>
#include <numbers>
#include <random>

namespace bgkmap::sim {
namespace {

// True if the point is inside solid matter: below the surface or in an overhang.
bool Solid(const World& w, const Eigen::Vector3d& p) {
  const double h = w.SurfaceHeight(p.x(), p.y());
  return (!std::isnan(h) && p.z() <= h) || w.InOverhang(p.x(), p.y(), p.z());
}

}  // namespace

std::vector<Point3f> SimulateScan(const World& world, const BeamModel& beams, const Pose& T,
                                  const RayCastOptions& opt) {
  std::mt19937 rng(opt.seed);
  std::normal_distribution<double> noise(0.0, beams.range_noise_std);
  std::vector<Point3f> out;
  out.reserve(beams.points_per_revolution());
  const Eigen::Vector3d origin = T.translation;
  for (int a = 0; a < beams.azimuth_steps; ++a) {
    const double az = 2.0 * std::numbers::pi * a / beams.azimuth_steps;
    for (double el_deg : beams.elevation_deg) {
      const double el = el_deg * std::numbers::pi / 180.0;
      const Eigen::Vector3d dir_s(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                  std::sin(el));
      const Eigen::Vector3d dir = T.rotation * dir_s;
      // March until the ray enters solid matter, then bisect the crossing to 1 mm.
      double prev = 0.0, t = opt.step_min;
      bool hit = false;
      const double top = world.MaxHeight();
      while (t <= beams.max_range) {
        // A rising ray above every surface has left the world (saves marching to max range).
        if (dir.z() >= 0.0 && origin.z() + t * dir.z() > top) break;
        if (Solid(world, origin + t * dir)) {
          hit = true;
          break;
        }
        prev = t;
        t += opt.step_min + opt.step_per_m * t;
      }
      if (!hit) continue;
      double lo = prev, hi = t;
      while (hi - lo > 1e-3) {
        const double mid = 0.5 * (lo + hi);
        (Solid(world, origin + mid * dir) ? hi : lo) = mid;
      }
      const double range = hi + noise(rng);
      if (range < beams.min_range || range > beams.max_range) continue;
      const Eigen::Vector3d p = range * dir_s;
      out.push_back(
          {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
    }
  }
  return out;
}

}  // namespace bgkmap::sim
