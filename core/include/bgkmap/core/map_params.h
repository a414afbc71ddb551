// Every parameter of a map, as data; defaults are the values a field is initialised with. The key
// names (the YAML contract, docs/configuration.md) are in map_param_table.h.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap {

// The mapping methods compared in the paper (Table 1, Fig. 5), and one beyond it.
enum class Method {
  kBgkPlus,   // "bgk+": BGK elevation, v at observed cells, BGK traversability inference.
  kBgkTrav,   // "bgk-trav": BGK elevation, v computed directly at every cell within l.
  kBaseline,  // "baseline": no inference, v at observed cells from raw elevations.
  kOneStep,   // "one-step": raw elevations, v at observed cells, BGK traversability inference.
  // "bgk-obstacle": as one-step, plus each observed cell's own v with the weight of a whole
  // neighbourhood, and a state that needs the Beta mean two deviations below the threshold
  // (docs/semantics.md, "bgk-obstacle").
  kBgkObstacle,
  // "bgk-ll": local-linear BGK elevation (a kernel-weighted plane per cell, from additive
  // moments) and BGK traversability, in both of which a cell's own observation weighs as much
  // as its whole kernel neighbourhood (docs/semantics.md, "bgk-ll").
  kBgkLocalLinear,
};

// How the points of one scan falling in one cell become that cell's training value y.
enum class Observation { kMax, kMean };

// Whether the map follows a changing world (docs/semantics.md, "Dynamics"): bounded confidence,
// free-space evidence and visible disagreement. kOff is the paper's pure accumulation, exactly.
enum class Dynamics { kOff, kOn };

std::string_view MethodName(Method m);
std::string_view ObservationName(Observation o);
std::string_view DynamicsName(Dynamics d);
Result<Method> ParseMethod(std::string_view name);
Result<Observation> ParseObservation(std::string_view name);
Result<Dynamics> ParseDynamics(std::string_view name);

// True for the methods whose traversability is a Beta posterior (bgk+, one-step, bgk-obstacle,
// bgk-ll);
// the others
// keep the latest directly computed value per cell.
bool InfersTraversability(Method m);
// True for the methods whose elevation is BGK regression (bgk+, bgk-trav, bgk-ll).
bool InfersElevation(Method m);
// True for the methods whose tiles keep plane moments (bgk-ll).
bool KeepsPlaneMoments(Method m);

// Every parameter, with its default. What each means, its key and its rule are in
// MapParamTable() (map_param_table.h), the one place that lists them.
struct MapParams {
  double resolution = 0.1;
  double kernel_length = 0.3;
  double lambda = 0.0;  // 0: no prior, as the paper
  double prior_mean = 0.0;
  double sigma2 = 0.01;
  double alpha0 = 0.001;
  double beta0 = 0.001;
  double robot_radius = 0.3;
  double step_crit = 0.15;
  double slope_crit_deg = 20.0;
  double roughness_crit = 0.05;
  // Vertical error of the robot's poses, one sigma per scan (metres; 0: off): step and
  // roughness discount what two scans of flat ground differ by (docs/semantics.md, "Pose noise").
  double pose_sigma_z = 0.0;
  std::array<double, 3> weights = {0.4, 0.4, 0.2};
  double trav_threshold = 0.5;
  double variance_threshold = 0.05;
  // Seen too little (dynamics on): a cell failing the state rule only for want of traversability
  // evidence, with less elevation weight than this many full-kernel observations, is unknown
  // (docs/semantics.md, "Seen too little"); 0: non-traversable, the paper's rule.
  double thin_evidence_weight = 0.5;
  // The same for a cell failing the variance alone, its thin evidence leaning traversable (thin
  // ground, not a thin sign of an obstacle): unknown below the larger of the two weights.
  double thin_ground_weight = 100.0;
  double min_range = 1.0;
  double max_range = 100.0;
  double max_height_above_sensor = 0.5;
  Observation observation = Observation::kMax;
  int tile_size = 64;
  Method method = Method::kBgkPlus;
  Dynamics dynamics = Dynamics::kOn;
  double max_confidence_scans = 20.0;
  double clear_margin = 0.2;
  double clear_decay = 0.05;
  double clear_ray_length = 2.0;
  // The robot's footprint (dynamics on): > 0 makes each scan's pose evidence of traversable
  // ground sensor_height below the sensor, within robot_radius (docs/semantics.md).
  double sensor_height = 0.0;
  double footprint_weight = 0.1;
  // The footprint as the vehicle's box (issue 24, P6): > 0 replaces the disk of robot_radius by
  // a footprint_length x footprint_width box turned to the sensor's heading, the sensor at
  // (footprint_sensor_x, footprint_sensor_y) from its centre (x forward); its cells' obstacle
  // evidence is cleared, the robot stands there. 0: the disk (docs/semantics.md, "Dynamics").
  double footprint_length = 0.0;
  double footprint_width = 0.0;
  double footprint_sensor_x = 0.0;
  double footprint_sensor_y = 0.0;
  // The self-filter (issue 24, P7): > 0 drops, as min_range does, every return of a sensor scan
  // inside the vehicle's own box: the footprint box (needs footprint_length and
  // footprint_width > 0; else off) grown by self_filter_margin on each side, in the sensor's
  // frame (x forward, the sensor at footprint_sensor_x/y from the box's centre), and higher than
  // self_filter_below under the sensor (docs/semantics.md, "Self-filter"). 0: off.
  double self_filter_below = 0.0;
  double self_filter_margin = 0.0;
  // Forgetting (dynamics on): > 0 halves every statistic's weight per half_life_s seconds of map
  // time (scan stamps), docs/semantics.md "Forgetting"; 0: off.
  double half_life_s = 0.0;
  // Transient objects (dynamics on, stamped scans; issue 24, P4): > 0 keeps aside the ground
  // under something that appears where the map saw traversable ground; unless it is still seen
  // transient_confirm_s after it appeared, the ground comes back once it has not been seen for
  // transient_expire_s (docs/semantics.md, "Transient objects"). 0: off.
  double transient_confirm_s = 0.0;
  double transient_expire_s = 1.0;

  // Checks every field (MapParamInfo::check); the message names the key, the value and the rule
  // broken.
  Status Validate() const;

  // Maps merge or reopen only if every parameter that shapes the stored statistics
  // (MapParamInfo::shapes_statistics) is equal; `why` names the first that differs.
  bool StatisticsCompatibleWith(const MapParams& other, std::string* why) const;
};

// Engine limits that keep integer cell and tile arithmetic exact: cell indices stay within
// +-kMaxCellIndex, so a stencil offset or a tile floor division can never overflow int32.
inline constexpr int kMaxCellIndex = (1 << 30);
inline constexpr int kMaxStencilRadiusCells = 64;
inline constexpr int kMinTileSize = 4;
inline constexpr int kMaxTileSize = 1024;

// Transient objects are on (transient_confirm_s > 0 with dynamics; docs/semantics.md).
bool KeepsTransients(const MapParams& p);

// All key names, in MapParamTable() order.
const std::vector<std::string_view>& MapParamKeys();

}  // namespace bgkmap
