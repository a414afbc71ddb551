#include "bgkmap/sim/ray_caster.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace bgkmap::sim {
namespace {

// Spans of a ray are tested against the world's height bound before marching them finely: from
// kMinSpan (about the DEM cell) up to kMaxSpan, doubling while they stay clear.
constexpr double kMinSpan = 1.0;
constexpr double kMaxSpan = 64.0;

// True if the point is inside solid matter: below the surface or in an overhang.
bool Solid(const World& w, const Eigen::Vector3d& p) {
  const double h = w.SurfaceHeight(p.x(), p.y());
  return (!std::isnan(h) && p.z() <= h) || w.InOverhang(p.x(), p.y(), p.z());
}

// True if the ray between ranges t0 and t1 stays above every surface and overhang below it:
// its lowest point (an end, the ray being straight) is above the bound of the spanned rectangle.
bool SpanIsClear(const World& w, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0,
                 double t1) {
  const Eigen::Vector3d a = o + t0 * d, b = o + t1 * d;
  const double bound = w.MaxHeightIn(std::min(a.x(), b.x()), std::min(a.y(), b.y()),
                                     std::max(a.x(), b.x()), std::max(a.y(), b.y()));
  return std::min(a.z(), b.z()) > bound;
}

}  // namespace

double CastRay(const World& world, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
               double max_range, const RayCastOptions& opt) {
  const auto step = [&](double t) { return opt.step_min + opt.step_per_m * t; };
  const double top = world.MaxHeight();
  double prev = 0.0, t = opt.step_min, span = kMinSpan;
  bool hit = false;
  while (!hit && t <= max_range) {
    // A rising ray above every surface has left the world.
    if (dir.z() >= 0.0 && origin.z() + t * dir.z() > top) break;
    const double t1 = std::min(t + span, max_range);
    if (SpanIsClear(world, origin, dir, t, t1)) {
      if (t1 >= max_range) break;
      prev = t1;
      t = t1 + step(t1);
      span = std::min(2.0 * span, kMaxSpan);
      continue;
    }
    if (span > kMinSpan) {
      span *= 0.5;
      continue;
    }
    // Near the surface: march finely over the next kMinSpan metres, then test spans again.
    for (const double end = t + kMinSpan; t <= max_range && t < end; t += step(t)) {
      if (Solid(world, origin + t * dir)) {
        hit = true;
        break;
      }
      prev = t;
    }
  }
  if (!hit) return std::numeric_limits<double>::quiet_NaN();
  // Bisect the crossing between the last free sample and the first solid one.
  double lo = prev, hi = t;
  while (hi - lo > 1e-3) {
    const double mid = 0.5 * (lo + hi);
    (Solid(world, origin + mid * dir) ? hi : lo) = mid;
  }
  return hi;
}

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
      const double hit = CastRay(world, origin, T.rotation * dir_s, beams.max_range, opt);
      if (std::isnan(hit)) continue;
      const double range = hit + noise(rng);
      if (range < beams.min_range || range > beams.max_range) continue;
      const Eigen::Vector3d p = range * dir_s;
      out.push_back(
          {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
    }
  }
  return out;
}

}  // namespace bgkmap::sim
