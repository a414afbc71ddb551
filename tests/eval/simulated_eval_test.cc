// A short stretch of the simulated city, mapped and scored end to end, and a flat world.
#include <gtest/gtest.h>

#include <memory>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/map_score.h"
#include "bgkmap/sim/city_world.h"
#include "bgkmap/sim/ground_truth.h"
#include "bgkmap/sim/ray_caster.h"
#include "bgkmap/sim/scenario.h"

namespace bgkmap {
namespace {

MapParams CityParams(Method method) {
  MapParams p;
  p.variance_threshold = 1.0;
  p.method = method;
  return p;
}

struct Simulated {
  std::vector<std::vector<Point3f>> scans;
  Raster truth;
};

Simulated Simulate(const sim::Scenario& s, const MapParams& params) {
  Simulated out;
  for (const Pose& pose : s.mapping_poses) {
    out.scans.push_back(sim::SimulateScan(*s.world, s.beams, pose));
  }
  const CellBox box = GridGeometry(params.resolution, params.tile_size)
                          .CellsOfRegion(s.xmin, s.ymin, s.xmax, s.ymax);
  sim::VisibilityMask mask(params, box);
  for (const Pose& pose : s.truth_poses) {
    EXPECT_TRUE(mask.AddScan(sim::SimulateScan(*s.world, s.beams, pose), pose).ok());
  }
  out.truth = sim::MakeGroundTruth(*s.world, params, mask);
  return out;
}

eval::MapScore MapAndScore(const sim::Scenario& s, const Simulated& data, Method method) {
  auto map = std::move(TerrainMap::Create(CityParams(method))).value();
  for (size_t k = 0; k < data.scans.size(); ++k) {
    EXPECT_TRUE(map->IntegrateScan(data.scans[k], s.mapping_poses[k]).ok());
  }
  return eval::ScoreMap(*map, data.truth);
}

TEST(SimulatedEvalTest, CityKerbsAndCarsAreFoundAndInferenceCoversMore) {
  const sim::Scenario s = sim::MakeCityScenario(/*length=*/6.0, 1.0, /*truth_spacing=*/0.5);
  const Simulated data = Simulate(s, CityParams(Method::kBgkPlus));
  const eval::MapScore bgk = MapAndScore(s, data, Method::kBgkPlus);
  const eval::MapScore baseline = MapAndScore(s, data, Method::kBaseline);
  ASSERT_GT(bgk.truth_cells, 1000);
  EXPECT_GT(bgk.coverage, baseline.coverage);
  EXPECT_LE(bgk.coverage, 1.0);
  EXPECT_GT(bgk.roc.positives, 0);  // kerbs, car and building walls
  EXPECT_GE(bgk.roc.auc, 0.0);
  EXPECT_LE(bgk.roc.auc, 1.0);
  EXPECT_GT(bgk.roc.auc, 0.8);
  EXPECT_GT(baseline.roc.auc, 0.5);
  EXPECT_LT(bgk.mse_ground, 0.01);
}

TEST(SimulatedEvalTest, TreeCanopyAboveTheSensorIsNoObstacle) {
  // The canopy hangs over the sidewalk and road edge; only the trunk is solid ground truth.
  const sim::CityWorld city;
  EXPECT_TRUE(city.InOverhang(8.6 - 2.0, 5.0, sim::CityWorld::RoadHeight(5.0) + 4.3));
  EXPECT_LT(city.SurfaceHeight(8.6 - 2.0, 5.0), 0.5);
  EXPECT_GT(city.SurfaceHeight(8.6, 5.0), 2.0);  // trunk
}

TEST(SimulatedEvalTest, KerbsAreTenToTwentyCentimetres) {
  for (double y = 0; y < 210; y += 0.7) {
    EXPECT_GE(sim::CityWorld::KerbHeight(y), 0.10 - 1e-12);
    EXPECT_LE(sim::CityWorld::KerbHeight(y), 0.20 + 1e-12);
  }
}

class FlatWorld : public sim::World {
 public:
  double SurfaceHeight(double, double) const override { return 0.0; }
  double MaxHeight() const override { return 1.0; }
};

TEST(SimulatedEvalTest, FlatWorldElevationErrorIsSmallAndAllTraversable) {
  sim::Scenario s;
  s.world = std::make_shared<FlatWorld>();
  s.beams = sim::Vlp16();
  for (double x : {0.0, 2.0, 4.0}) {
    Pose p;
    p.translation = {x, 0.0, 1.0};
    s.mapping_poses.push_back(p);
    s.truth_poses.push_back(p);
  }
  s.xmin = -5;
  s.xmax = 9;
  s.ymin = -5;
  s.ymax = 5;
  const Simulated data = Simulate(s, CityParams(Method::kBgkPlus));
  const eval::MapScore score = MapAndScore(s, data, Method::kBgkPlus);
  ASSERT_GT(score.known_cells, 100);
  EXPECT_LT(score.mse_all, 1e-3);
  EXPECT_EQ(score.roc.positives, 0);  // nothing is an obstacle on a plane
}

}  // namespace
}  // namespace bgkmap
