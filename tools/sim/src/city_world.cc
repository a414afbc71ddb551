#include "bgkmap/sim/city_world.h"

#include <cmath>
#include <numbers>

namespace bgkmap::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Position inside a repeating pattern of `period` metres starting at `offset`.
double Phase(double y, double period, double offset) {
  return std::fmod(std::fmod(y - offset, period) + period, period);
}
int Index(double y, double period, double offset) {
  return static_cast<int>(std::floor((y - offset) / period));
}

bool InDisk(double x, double y, double cx, double cy, double r) {
  return (x - cx) * (x - cx) + (y - cy) * (y - cy) < r * r;
}

// Trees stand on both sidewalks every 20 m (right side shifted by 10 m).
constexpr double kTreeX = 8.6, kTreePeriod = 20.0, kTreeOffset = 5.0;
constexpr double kTrunkRadius = 0.18, kTrunkTop = 2.6;
constexpr double kCanopyRadius = 2.3, kCanopyCentre = 4.2, kCanopyHalfHeight = 1.5;

double TreeY(double x, double y) {
  const double off = kTreeOffset + (x < 0 ? 10.0 : 0.0);
  return off + kTreePeriod * Index(y + kTreePeriod / 2, kTreePeriod, off);
}

}  // namespace

double CityWorld::RoadHeight(double y) { return 0.6 * std::sin(2 * kPi * y / kLength); }
double CityWorld::KerbHeight(double y) { return 0.15 + 0.05 * std::sin(2 * kPi * y / 53.0); }

double CityWorld::SurfaceHeight(double x, double y) const {
  const double base = RoadHeight(y);
  const double ax = std::abs(x);
  if (y < -15.0 || y > length_ + 15.0 || ax > kHalfWidth) return base + 10.0;  // closing walls

  if (ax < kRoadHalf) {
    double z = base + 0.04 * (1.0 - (x / kRoadHalf) * (x / kRoadHalf));  // crown
    // Parked cars along both kerbs, 4.4 m long, mostly every 13 m.
    const double side_off = x < 0 ? 8.0 : 14.5;
    const int k = Index(y, 13.0, side_off);
    if (ax > 3.9 && ax < 5.7 && Phase(y, 13.0, side_off) < 4.4 && (k * 5) % 3 != 0) z += 1.45;
    return z;
  }

  const double kerb = KerbHeight(y);
  if (ax < kSidewalkEnd) {
    // Kerb-cut ramps, 3 m long, every 35 m, alternating sides: a 1.5 m incline instead of a step.
    const double ramp_off = x < 0 ? 17.0 : 34.5;
    double rise = kerb;
    if (Phase(y, 70.0, ramp_off) < 3.0 && ax < kRoadHalf + 1.5)
      rise = kerb * (ax - kRoadHalf) / 1.5;
    double z = base + rise + 0.015 * (ax - kRoadHalf);  // cross fall towards the road
    // Poles (lamp posts) every 25 m near the building line.
    const double pole_y = 12.0 + 25.0 * Index(y + 12.5, 25.0, 12.0);
    if (InDisk(ax, y, 9.9, pole_y, 0.12)) z += 6.0;
    // Tree trunks; the canopy is an overhang (InOverhang).
    if (InDisk(ax, y, kTreeX, TreeY(x, y), kTrunkRadius)) z = base + kerb + kTrunkTop;
    return z;
  }

  // Buildings in 40 m blocks with 8 m alleys; the alleys continue at sidewalk level.
  const int block = Index(y, 40.0, x < 0 ? 0.0 : 20.0);
  const bool alley = Phase(y, 40.0, x < 0 ? 0.0 : 20.0) > 32.0;
  if (alley) return base + kerb + 0.015 * (kSidewalkEnd - kRoadHalf);
  return base + 8.0 + 4.0 * ((block * 7 + (x < 0 ? 1 : 0)) % 3);
}

bool CityWorld::InOverhang(double x, double y, double z) const {
  const double ax = std::abs(x);
  if (ax < kTreeX - kCanopyRadius || ax > kTreeX + kCanopyRadius) return false;
  const double dx = ax - kTreeX, dy = y - TreeY(x, y);
  const double dz = (z - RoadHeight(y) - KerbHeight(y) - kCanopyCentre) / kCanopyHalfHeight;
  return (dx * dx + dy * dy) / (kCanopyRadius * kCanopyRadius) + dz * dz < 1.0;
}

}  // namespace bgkmap::sim
