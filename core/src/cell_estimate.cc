#include "bgkmap/core/cell_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace bgkmap {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr Layer kAllLayers[] = {Layer::kElevation,      Layer::kElevationVariance,
                                Layer::kTraversability, Layer::kTraversabilityVariance,
                                Layer::kState,          Layer::kElevationWeight};
}  // namespace

std::string_view LayerName(Layer layer) {
  switch (layer) {
    case Layer::kElevation:
      return "elevation";
    case Layer::kElevationVariance:
      return "elevation_variance";
    case Layer::kTraversability:
      return "traversability";
    case Layer::kTraversabilityVariance:
      return "traversability_variance";
    case Layer::kState:
      return "state";
    case Layer::kElevationWeight:
      return "elevation_weight";
  }
  return "?";
}

Result<Layer> ParseLayer(std::string_view name) {
  for (Layer l : kAllLayers) {
    if (name == LayerName(l)) return l;
  }
  return Status::InvalidArgument("layer '" + std::string(name) +
                                 "': must be one of elevation, elevation_variance, traversability, "
                                 "traversability_variance, state, elevation_weight");
}

float CellEstimate::Get(Layer layer) const {
  switch (layer) {
    case Layer::kElevation:
      return elevation;
    case Layer::kElevationVariance:
      return elevation_variance;
    case Layer::kTraversability:
      return traversability;
    case Layer::kTraversabilityVariance:
      return traversability_variance;
    case Layer::kState:
      return static_cast<float>(state);
    case Layer::kElevationWeight:
      return elevation_weight;
  }
  return kNaN;
}

double Disagreement(double w, double s, double q) {
  if (!(w > 0.0)) return 0.0;
  const double mean = s / w;
  return std::max(0.0, q / w - mean * mean);
}

CellEstimate EstimateCell(const MapParams& p, double w, double s, double q, float a, float b) {
  CellEstimate e{kNaN, kNaN, kNaN, kNaN, CellState::kUnknown, static_cast<float>(w)};
  const double ab = static_cast<double>(a) + static_cast<double>(b);
  const bool known = w > 0.0 || ab > 0.0;
  if (!known) {
    e.elevation_weight = kNaN;
    return e;
  }
  const bool dynamic = p.dynamics == Dynamics::kOn;
  double disagreement = 0.0;
  if (w > 0.0) {
    const double lw = p.lambda + w;
    if (dynamic) disagreement = Disagreement(w, s, q);
    e.elevation = static_cast<float>((p.lambda * p.prior_mean + s) / lw);
    e.elevation_variance = static_cast<float>(p.sigma2 / lw + disagreement);
  }
  if (InfersTraversability(p.method)) {
    const double alpha = p.alpha0 + a;
    const double beta = p.beta0 + b;
    const double sum = alpha + beta;
    e.traversability = static_cast<float>(alpha / sum);
    e.traversability_variance = static_cast<float>(alpha * beta / (sum * sum * (sum + 1.0)));
  } else if (ab > 0.0) {
    e.traversability = static_cast<float>(a / ab);
    e.traversability_variance = 0.0f;
  }
  // bgk-obstacle: an uncertain cell is not traversable; its Beta mean must clear the threshold
  // by two standard deviations.
  const double margin = p.method == Method::kBgkObstacle
                            ? 2.0 * std::sqrt(static_cast<double>(e.traversability_variance))
                            : 0.0;
  // NaN comparisons are false: a known cell without a traversability value is non-traversable.
  const bool traversable = e.traversability + margin < p.trav_threshold &&
                           e.traversability_variance < p.variance_threshold &&
                           disagreement <= p.step_crit * p.step_crit;
  e.state = traversable ? CellState::kTraversable : CellState::kNonTraversable;
  return e;
}

}  // namespace bgkmap
