// A valid MapParams whose every parameter differs from its default, for round trips that must
// cover every entry of MapParamTable().
#pragma once

#include <string>

#include "bgkmap/core/map_param_table.h"
#include "bgkmap/core/map_params.h"

namespace bgkmap::testing_support {

inline MapParams NonDefaultParams() {
  MapParams p;
  p.resolution = 0.2;
  p.kernel_length = 0.1 + 0.2;  // 0.30000000000000004: only a shortest round trip keeps it
  p.lambda = 0.5;
  p.prior_mean = -3.25;
  p.sigma2 = 0.02;
  p.alpha0 = 0.01;
  p.beta0 = 0.02;
  p.robot_radius = 0.5;
  p.step_crit = 0.2;
  p.slope_crit_deg = 25;
  p.roughness_crit = 0.08;
  p.weights = {0.1, 0.7, 0.2};
  p.trav_threshold = 0.4;
  p.variance_threshold = 0.1;
  p.thin_evidence_weight = 1.5;
  p.thin_ground_weight = 2.5;
  p.pose_sigma_z = 0.02;
  p.min_range = 0.5;
  p.max_range = 80;
  p.max_height_above_sensor = -0.25;
  p.observation = Observation::kMean;
  p.tile_size = 32;
  p.method = Method::kOneStep;
  p.dynamics = Dynamics::kOff;
  p.max_confidence_scans = 7.5;
  p.clear_margin = 0.35;
  p.clear_decay = 0.25;
  p.clear_ray_length = 4.5;
  p.sensor_height = 0.75;
  p.footprint_weight = 0.3;
  p.half_life_s = 12.5;
  p.footprint_length = 4.5;
  p.footprint_width = 1.8;
  p.footprint_sensor_x = -0.4;
  p.footprint_sensor_y = 0.1;
  p.self_filter_below = 0.7;
  p.self_filter_margin = 0.15;
  p.transient_confirm_s = 2.5;
  p.transient_expire_s = 0.75;
  return p;
}

// The keys whose values differ between `a` and `b`, comma-separated ("" if none).
inline std::string DifferingKeys(const MapParams& a, const MapParams& b) {
  std::string keys;
  for (const MapParamInfo& info : MapParamTable()) {
    if (!info.Equal(a, b)) keys += (keys.empty() ? "" : ", ") + std::string(info.key);
  }
  return keys;
}

// The keys NonDefaultParams() leaves at their defaults: must be "" (extend it with a new key).
inline std::string KeysAtDefault(const MapParams& p) {
  std::string keys;
  const MapParams defaults;
  for (const MapParamInfo& info : MapParamTable()) {
    if (info.Equal(p, defaults)) keys += (keys.empty() ? "" : ", ") + std::string(info.key);
  }
  return keys;
}

}  // namespace bgkmap::testing_support
