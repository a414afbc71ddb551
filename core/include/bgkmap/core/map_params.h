// Every parameter of a map, as data. The key names in comments are the YAML contract
// (see docs/configuration.md); defaults are the values a field is initialised with.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap {

// The mapping methods compared in the paper (Table 1, Fig. 5).
enum class Method {
  kBgkPlus,   // "bgk+": BGK elevation, v at observed cells, BGK traversability inference.
  kBgkTrav,   // "bgk-trav": BGK elevation, v computed directly at every cell within l.
  kBaseline,  // "baseline": no inference, v at observed cells from raw elevations.
  kOneStep,   // "one-step": raw elevations, v at observed cells, BGK traversability inference.
};

// How the points of one scan falling in one cell become that cell's training value y.
enum class Observation { kMax, kMean };

std::string_view MethodName(Method m);
std::string_view ObservationName(Observation o);
Result<Method> ParseMethod(std::string_view name);
Result<Observation> ParseObservation(std::string_view name);

// True for the methods whose traversability is a Beta posterior (bgk+, one-step); the others
// keep the latest directly computed value per cell.
bool InfersTraversability(Method m);
// True for the methods whose elevation is BGK regression (bgk+, bgk-trav).
bool InfersElevation(Method m);

struct MapParams {
  double resolution = 0.1;       // resolution: cell edge, metres.
  double kernel_length = 0.3;    // kernel_length: sparse kernel support l, metres.
  double lambda = 0.0;           // lambda: prior confidence in prior_mean (0 = none, as the paper).
  double prior_mean = 0.0;       // prior_mean: mu0, metres.
  double sigma2 = 0.01;          // sigma2: observation noise variance, m^2.
  double alpha0 = 0.001;         // alpha0: Beta prior pseudo-count for "non-traversable".
  double beta0 = 0.001;          // beta0: Beta prior pseudo-count for "traversable".
  double robot_radius = 0.3;     // robot_radius: neighbourhood for step/slope/roughness, metres.
  double step_crit = 0.15;       // step_crit: critical step height, metres.
  double slope_crit_deg = 20.0;  // slope_crit_deg: critical slope, degrees.
  double roughness_crit = 0.05;  // roughness_crit: critical roughness, metres.
  std::array<double, 3> weights = {0.4, 0.4, 0.2};  // weights: [w_step, w_slope, w_rough], sum 1.
  double trav_threshold = 0.5;                      // trav_threshold: v_th of Eq. 6.
  double variance_threshold = 0.05;                 // variance_threshold: sigma_th^2 of Eq. 6.
  double min_range = 1.0;    // min_range: drop closer points (the robot's own body), metres.
  double max_range = 100.0;  // max_range: drop farther points, metres.
  double max_height_above_sensor = 0.5;         // max_height_above_sensor: drop overhangs, metres.
  Observation observation = Observation::kMax;  // observation: max | mean.
  int tile_size = 64;                           // tile_size: cells per tile edge.
  Method method = Method::kBgkPlus;             // method: bgk+ | bgk-trav | baseline | one-step.

  // Checks every field; the message names the key, the value and the rule broken.
  Status Validate() const;

  // Parameters that shape the stored statistics (all but sigma2, alpha0, beta0 and the two
  // thresholds, which only enter derived layers). Maps merge or reopen only if these are equal.
  bool StatisticsCompatibleWith(const MapParams& other, std::string* why) const;
};

// Engine limits that keep integer cell and tile arithmetic exact: cell indices stay within
// +-kMaxCellIndex, so a stencil offset or a tile floor division can never overflow int32.
inline constexpr int kMaxCellIndex = (1 << 30);
inline constexpr int kMaxStencilRadiusCells = 64;
inline constexpr int kMinTileSize = 4;
inline constexpr int kMaxTileSize = 1024;

// All YAML key names, in documentation order.
const std::vector<std::string_view>& MapParamKeys();

}  // namespace bgkmap
