// The paper's two simulated experiments as data: a world, a sensor, the poses scans are taken
// from for mapping, the denser poses of the ground-truth scan set, and the evaluated area.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/sim/beam_model.h"
#include "bgkmap/sim/dem_world.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

struct Scenario {
  std::string name;
  std::shared_ptr<const World> world;
  BeamModel beams;
  std::vector<Pose> mapping_poses;  // T_world_sensor of each mapping scan, in time order
  std::vector<Pose> truth_poses;    // the dense ground-truth scan set
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;  // evaluated area, world frame
};

// City (Sec. 3.1.1): VLP-16 1.0 m above the road centre, heading along the road, a scan every
// `mapping_spacing` metres over `length` metres (paper: 1 m over 210 m); ground-truth scans every
// `truth_spacing` (paper: 0.1 m). Evaluated area: |x| <= 25 m, 0 <= y <= length. The street is
// 210 m long, or `length` if longer (CityWorld).
Scenario MakeCityScenario(double length = 210.0, double mapping_spacing = 1.0,
                          double truth_spacing = 0.1);

// Aerial (Sec. 3.1.2): the DEM (NODATA filled, FillNoData) with rocks and ditches, an HDL-32E at a
// fixed altitude
// (`clearance` above the highest terrain of the area) over n x n positions `spacing` apart
// (paper: 13 x 13, 10 m), centred on the DEM; ground-truth positions every `truth_spacing`.
// The evaluated area is the square the positions span.
Scenario MakeAerialScenario(HeightGrid dem, int n = 13, double spacing = 10.0,
                            double truth_spacing = 2.5, double clearance = 4.0);

// Flat: level ground at z = 0 and nothing else (objects come from a change script), a VLP-16
// kFlatSensorHeight above it heading along +x. `scans` scans evenly spaced over `length` metres
// from the origin (0: a robot standing still); ground-truth scans every `truth_spacing` metres
// along the same path (one, at the origin, when standing still). Evaluated area: 20 m around the
// path.
inline constexpr double kFlatSensorHeight = 1.5;
Scenario MakeFlatScenario(int scans, double length = 0.0, double truth_spacing = 0.5);

}  // namespace bgkmap::sim
