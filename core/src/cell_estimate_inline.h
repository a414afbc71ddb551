// The per-cell estimate (EstimateCell, cell_estimate.h) as an inline function of the map's
// constants, for the loops that estimate many cells (ExtractRaster): EstimateCell itself calls
// it, so both give the same bits.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/map_params.h"

namespace bgkmap::internal {

// What EstimateCell derives from the parameters alone, once per map instead of per cell.
struct EstimateConstants {
  bool infers_traversability;
  bool dynamic;
  double full_kernel_weight;  // FullKernelWeight(p)

  static EstimateConstants Of(const MapParams& p) {
    return {InfersTraversability(p.method), p.dynamics == Dynamics::kOn, FullKernelWeight(p)};
  }
};

// Disagreement() (cell_estimate.h), inline for the loops.
inline double DisagreementOf(double w, double s, double q) {
  if (!(w > 0.0)) return 0.0;
  const double mean = s / w;
  return std::max(0.0, q / w - mean * mean);
}

// The conditions of the state rule a known cell fails (BlockReason bits), on the estimate's own
// float values so that 0 is exactly "traversable".
inline uint8_t FailedConditions(const MapParams& p, bool infers_traversability,
                                const CellEstimate& e, double ab, double d) {
  const bool no_value = infers_traversability ? ab == 0.0 : std::isnan(e.traversability);
  // bgk-obstacle: an uncertain cell is not traversable; its Beta mean must clear the threshold
  // by two standard deviations.
  const double margin = p.method == Method::kBgkObstacle
                            ? 2.0 * std::sqrt(static_cast<double>(e.traversability_variance))
                            : 0.0;
  // NaN comparisons are false: a known cell without a traversability value is non-traversable.
  uint8_t r = 0;
  if (!(e.traversability + margin < p.trav_threshold)) r |= kBlockedMean;
  if (!(e.traversability_variance < p.variance_threshold)) r |= kBlockedVariance;
  if (!(d <= p.step_crit * p.step_crit)) r |= kBlockedDisagreement;
  // No evidence at all fails the mean and the variance through the prior alone: say so instead.
  if (r != 0 && no_value) r = kBlockedNoValue | (r & kBlockedDisagreement);
  return r;
}

// P3' (docs/semantics.md, "Seen too little"): with dynamics, a cell that fails only for want of
// traversability evidence (no value, or the variance alone) and holds less elevation weight than
// thin_evidence_weight full-kernel observations is unknown, not an obstacle: it was barely seen.
// Failing the variance alone, its thin evidence leans traversable (thin ground), and up to
// thin_ground_weight if that is more (by default above the confidence cap: always). A cell
// without a value seen more than that had its Beta evidence reset beside something forgotten
// (a wall beside a vanished box) and stays blocked. Without dynamics the paper's rule.
inline CellState StateOf(const MapParams& p, const EstimateConstants& k, uint8_t reasons,
                         double w) {
  if (reasons == 0) return CellState::kTraversable;
  const bool thin = reasons == kBlockedNoValue || reasons == kBlockedVariance;
  const double limit = reasons == kBlockedVariance
                           ? std::max(p.thin_evidence_weight, p.thin_ground_weight)
                           : p.thin_evidence_weight;
  const bool seen_little = w < limit * k.full_kernel_weight;
  return thin && seen_little && k.dynamic ? CellState::kUnknown : CellState::kNonTraversable;
}

inline CellEstimate EstimateCellWith(const MapParams& p, const EstimateConstants& k, double w,
                                     double s, double q, float a, float b, const double* plane) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  CellEstimate e{kNaN, kNaN, kNaN, kNaN, CellState::kUnknown, static_cast<float>(w), kNaN, 0};
  const double ab = static_cast<double>(a) + static_cast<double>(b);
  const bool known = w > 0.0 || ab > 0.0;
  if (!known) {
    e.elevation_weight = kNaN;
    return e;
  }
  double disagreement = 0.0;
  if (w > 0.0) {
    const double lw = p.lambda + w;
    if (plane != nullptr) {
      const LocalPlane fit = FitLocalPlane(p, w, s, k.dynamic ? q : 0.0, plane);
      if (k.dynamic) disagreement = fit.residual;
      e.elevation = static_cast<float>(fit.elevation);
      e.elevation_variance =
          static_cast<float>(p.sigma2 * (1.0 / lw + fit.leverage) + disagreement);
    } else {
      if (k.dynamic) disagreement = DisagreementOf(w, s, q);
      e.elevation = static_cast<float>((p.lambda * p.prior_mean + s) / lw);
      e.elevation_variance = static_cast<float>(p.sigma2 / lw + disagreement);
    }
    if (k.dynamic) e.disagreement = static_cast<float>(std::sqrt(disagreement));
  }
  if (k.infers_traversability) {
    const double alpha = p.alpha0 + a;
    const double beta = p.beta0 + b;
    const double sum = alpha + beta;
    e.traversability = static_cast<float>(alpha / sum);
    e.traversability_variance = static_cast<float>(alpha * beta / (sum * sum * (sum + 1.0)));
  } else if (ab > 0.0) {
    e.traversability = static_cast<float>(a / ab);
    e.traversability_variance = 0.0f;
  }
  e.block_reasons = FailedConditions(p, k.infers_traversability, e, ab, disagreement);
  e.state = StateOf(p, k, e.block_reasons, w);
  return e;
}

}  // namespace bgkmap::internal
