#include "bgkmap/sim/scenario.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "bgkmap/sim/box_world.h"
#include "bgkmap/sim/city_world.h"

namespace bgkmap::sim {
namespace {

Pose At(double x, double y, double z, double yaw) {
  Pose p;
  p.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation = {x, y, z};
  return p;
}

// n + 1 evenly spaced values from 0 to length (inclusive), computed without accumulated error.
std::vector<double> Stations(double length, double spacing) {
  const int n = static_cast<int>(std::lround(length / spacing));
  std::vector<double> s;
  for (int i = 0; i <= n; ++i) s.push_back(i * spacing);
  return s;
}

}  // namespace

Scenario MakeCityScenario(double length, double mapping_spacing, double truth_spacing) {
  Scenario s;
  s.name = "city";
  s.world = std::make_shared<CityWorld>(length);
  s.beams = Vlp16();
  const double heading = std::numbers::pi / 2;  // along +y
  for (double y : Stations(length, mapping_spacing)) {
    s.mapping_poses.push_back(At(0.0, y, CityWorld::RoadHeight(y) + 1.0, heading));
  }
  for (double y : Stations(length, truth_spacing)) {
    s.truth_poses.push_back(At(0.0, y, CityWorld::RoadHeight(y) + 1.0, heading));
  }
  s.xmin = -CityWorld::kHalfWidth;
  s.xmax = CityWorld::kHalfWidth;
  s.ymin = 0.0;
  s.ymax = length;
  return s;
}

Scenario MakeAerialScenario(HeightGrid dem, int n, double spacing, double truth_spacing,
                            double clearance) {
  const double cx = dem.x0 + 0.5 * dem.cols * dem.cellsize;
  const double cy = dem.y0 + 0.5 * dem.rows * dem.cellsize;
  const double half = 0.5 * (n - 1) * spacing;
  ObstacleOptions obstacles;
  obstacles.xmin = cx - half;
  obstacles.xmax = cx + half;
  obstacles.ymin = cy - half;
  obstacles.ymax = cy + half;
  FillNoData(dem);  // water and unmeasured patches become closed terrain
  auto world = std::make_shared<DemWorld>(std::move(dem), obstacles);

  // Fixed altitude: the highest terrain of the area plus the clearance.
  double top = -1e300;
  for (double y = cy - half; y <= cy + half; y += 1.0) {
    for (double x = cx - half; x <= cx + half; x += 1.0) {
      const double z = world->SurfaceHeight(x, y);
      if (!std::isnan(z)) top = std::max(top, z);
    }
  }
  const double altitude = top + clearance;

  Scenario s;
  s.name = "aerial";
  s.world = world;
  s.beams = Hdl32e();
  // A lawnmower flight: rows south to north, alternating direction.
  for (int j = 0; j < n; ++j) {
    for (int k = 0; k < n; ++k) {
      const int i = (j % 2 == 0) ? k : n - 1 - k;
      s.mapping_poses.push_back(At(cx - half + i * spacing, cy - half + j * spacing, altitude, 0));
    }
  }
  for (double dy : Stations(2 * half, truth_spacing)) {
    for (double dx : Stations(2 * half, truth_spacing)) {
      s.truth_poses.push_back(At(cx - half + dx, cy - half + dy, altitude, 0));
    }
  }
  s.xmin = cx - half;
  s.xmax = cx + half;
  s.ymin = cy - half;
  s.ymax = cy + half;
  return s;
}

Scenario MakeFlatScenario(int scans, double length, double truth_spacing) {
  Scenario s;
  s.name = "flat";
  s.world = std::make_shared<BoxWorld>();
  s.beams = Vlp16();
  for (int k = 0; k < scans; ++k) {
    const double x = scans > 1 ? length * k / (scans - 1) : 0.0;
    s.mapping_poses.push_back(At(x, 0.0, kFlatSensorHeight, 0.0));
  }
  const std::vector<double> stations =
      length > 0 ? Stations(length, truth_spacing) : std::vector<double>{0.0};
  for (double x : stations) s.truth_poses.push_back(At(x, 0.0, kFlatSensorHeight, 0.0));
  constexpr double kMargin = 20.0;
  s.xmin = -kMargin;
  s.xmax = length + kMargin;
  s.ymin = -kMargin;
  s.ymax = kMargin;
  return s;
}

}  // namespace bgkmap::sim
