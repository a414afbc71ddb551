#include "bgkmap/core/map_params.h"

#include <cmath>
#include <sstream>

namespace bgkmap {
namespace {

std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

Status Bad(std::string_view key, double value, std::string_view rule) {
  return Status::InvalidArgument(std::string(key) + " = " + Num(value) + ": " + std::string(rule));
}

// Positive and finite.
Status RequirePositive(std::string_view key, double v) {
  if (!std::isfinite(v) || v <= 0) return Bad(key, v, "must be a finite number > 0");
  return Status::Ok();
}

}  // namespace

std::string_view MethodName(Method m) {
  switch (m) {
    case Method::kBgkPlus:
      return "bgk+";
    case Method::kBgkTrav:
      return "bgk-trav";
    case Method::kBaseline:
      return "baseline";
    case Method::kOneStep:
      return "one-step";
  }
  return "?";
}

std::string_view ObservationName(Observation o) { return o == Observation::kMax ? "max" : "mean"; }

Result<Method> ParseMethod(std::string_view name) {
  for (Method m : {Method::kBgkPlus, Method::kBgkTrav, Method::kBaseline, Method::kOneStep}) {
    if (name == MethodName(m)) return m;
  }
  return Status::InvalidArgument("method = " + std::string(name) +
                                 ": must be one of bgk+, bgk-trav, baseline, one-step");
}

Result<Observation> ParseObservation(std::string_view name) {
  if (name == "max") return Observation::kMax;
  if (name == "mean") return Observation::kMean;
  return Status::InvalidArgument("observation = " + std::string(name) +
                                 ": must be one of max, mean");
}

bool InfersTraversability(Method m) { return m == Method::kBgkPlus || m == Method::kOneStep; }
bool InfersElevation(Method m) { return m == Method::kBgkPlus || m == Method::kBgkTrav; }

Status MapParams::Validate() const {
  Status s;
  if (!(s = RequirePositive("resolution", resolution)).ok()) return s;
  if (resolution < 1e-3 || resolution > 100) {
    return Bad("resolution", resolution, "must lie in [0.001, 100] metres");
  }
  if (!(s = RequirePositive("kernel_length", kernel_length)).ok()) return s;
  if (kernel_length < resolution) {
    return Bad("kernel_length", kernel_length,
               "must be >= resolution (" + Num(resolution) + "), or no neighbour is ever inferred");
  }
  if (kernel_length / resolution > kMaxStencilRadiusCells) {
    return Bad("kernel_length", kernel_length,
               "must be <= " + std::to_string(kMaxStencilRadiusCells) + " * resolution");
  }
  if (!std::isfinite(lambda) || lambda < 0) return Bad("lambda", lambda, "must be finite and >= 0");
  if (!std::isfinite(prior_mean)) return Bad("prior_mean", prior_mean, "must be finite");
  if (!(s = RequirePositive("sigma2", sigma2)).ok()) return s;
  if (!(s = RequirePositive("alpha0", alpha0)).ok()) return s;
  if (!(s = RequirePositive("beta0", beta0)).ok()) return s;
  if (!(s = RequirePositive("robot_radius", robot_radius)).ok()) return s;
  if (robot_radius < resolution) {
    return Bad("robot_radius", robot_radius,
               "must be >= resolution (" + Num(resolution) + ") to span the 3 cells a plane needs");
  }
  if (robot_radius / resolution > kMaxStencilRadiusCells) {
    return Bad("robot_radius", robot_radius,
               "must be <= " + std::to_string(kMaxStencilRadiusCells) + " * resolution");
  }
  if (!(s = RequirePositive("step_crit", step_crit)).ok()) return s;
  if (!(s = RequirePositive("slope_crit_deg", slope_crit_deg)).ok()) return s;
  if (slope_crit_deg > 90) return Bad("slope_crit_deg", slope_crit_deg, "must be <= 90 degrees");
  if (!(s = RequirePositive("roughness_crit", roughness_crit)).ok()) return s;
  double sum = 0;
  for (double w : weights) {
    if (!std::isfinite(w) || w < 0) {
      return Bad("weights", w, "every weight must be finite and >= 0");
    }
    sum += w;
  }
  if (std::abs(sum - 1.0) > 1e-6) {
    return Bad("weights", sum, "[w_step, w_slope, w_rough] must sum to 1 (paper Eq. 5)");
  }
  if (!std::isfinite(trav_threshold) || trav_threshold <= 0 || trav_threshold > 1) {
    return Bad("trav_threshold", trav_threshold, "must lie in (0, 1]");
  }
  if (!std::isfinite(variance_threshold) || variance_threshold <= 0) {
    return Bad("variance_threshold", variance_threshold, "must be a finite number > 0");
  }
  if (!std::isfinite(min_range) || min_range < 0) {
    return Bad("min_range", min_range, "must be finite and >= 0");
  }
  if (!std::isfinite(max_range) || max_range <= min_range) {
    return Bad("max_range", max_range, "must be finite and > min_range (" + Num(min_range) + ")");
  }
  if (std::isnan(max_height_above_sensor)) {
    return Bad("max_height_above_sensor", max_height_above_sensor, "must be a number");
  }
  if (tile_size < kMinTileSize || tile_size > kMaxTileSize) {
    return Bad("tile_size", tile_size,
               "must lie in [" + std::to_string(kMinTileSize) + ", " +
                   std::to_string(kMaxTileSize) + "] cells");
  }
  return Status::Ok();
}

bool MapParams::StatisticsCompatibleWith(const MapParams& o, std::string* why) const {
  auto differ = [&](std::string_view key, double a, double b) {
    if (a == b) return false;
    if (why) *why = std::string(key) + " differs (" + Num(a) + " vs " + Num(b) + ")";
    return true;
  };
  if (differ("resolution", resolution, o.resolution) ||
      differ("tile_size", tile_size, o.tile_size) ||
      differ("kernel_length", kernel_length, o.kernel_length) ||
      // The elevation a scan's v is computed from depends on the prior too.
      differ("lambda", lambda, o.lambda) || differ("prior_mean", prior_mean, o.prior_mean) ||
      differ("robot_radius", robot_radius, o.robot_radius) ||
      differ("step_crit", step_crit, o.step_crit) ||
      differ("slope_crit_deg", slope_crit_deg, o.slope_crit_deg) ||
      differ("roughness_crit", roughness_crit, o.roughness_crit) ||
      differ("weights[0]", weights[0], o.weights[0]) ||
      differ("weights[1]", weights[1], o.weights[1]) ||
      differ("weights[2]", weights[2], o.weights[2]) ||
      differ("min_range", min_range, o.min_range) || differ("max_range", max_range, o.max_range) ||
      differ("max_height_above_sensor", max_height_above_sensor, o.max_height_above_sensor)) {
    return false;
  }
  if (observation != o.observation) {
    if (why) *why = "observation differs";
    return false;
  }
  if (method != o.method) {
    if (why) {
      *why = "method differs (" + std::string(MethodName(method)) + " vs " +
             std::string(MethodName(o.method)) + ")";
    }
    return false;
  }
  return true;
}

const std::vector<std::string_view>& MapParamKeys() {
  static const std::vector<std::string_view> keys = {"resolution",
                                                     "kernel_length",
                                                     "lambda",
                                                     "prior_mean",
                                                     "sigma2",
                                                     "alpha0",
                                                     "beta0",
                                                     "robot_radius",
                                                     "step_crit",
                                                     "slope_crit_deg",
                                                     "roughness_crit",
                                                     "weights",
                                                     "trav_threshold",
                                                     "variance_threshold",
                                                     "min_range",
                                                     "max_range",
                                                     "max_height_above_sensor",
                                                     "observation",
                                                     "tile_size",
                                                     "method"};
  return keys;
}

}  // namespace bgkmap
