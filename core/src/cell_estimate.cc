#include "bgkmap/core/cell_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "bgkmap/core/sparse_kernel.h"

namespace bgkmap {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr Layer kAllLayers[] = {Layer::kElevation,      Layer::kElevationVariance,
                                Layer::kTraversability, Layer::kTraversabilityVariance,
                                Layer::kState,          Layer::kElevationWeight,
                                Layer::kDisagreement,   Layer::kBlockReason};
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
    case Layer::kDisagreement:
      return "disagreement";
    case Layer::kBlockReason:
      return "block_reason";
  }
  return "?";
}

Result<Layer> ParseLayer(std::string_view name) {
  for (Layer l : kAllLayers) {
    if (name == LayerName(l)) return l;
  }
  return Status::InvalidArgument("layer '" + std::string(name) +
                                 "': must be one of elevation, elevation_variance, traversability, "
                                 "traversability_variance, state, elevation_weight, disagreement, "
                                 "block_reason");
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
    case Layer::kDisagreement:
      return disagreement;
    case Layer::kBlockReason:
      return std::isnan(elevation_weight) ? kNaN : static_cast<float>(block_reasons);
  }
  return kNaN;
}

double Disagreement(double w, double s, double q) {
  if (!(w > 0.0)) return 0.0;
  const double mean = s / w;
  return std::max(0.0, q / w - mean * mean);
}

LocalPlane FitLocalPlane(const MapParams& p, double w, double s, double q, const double* m) {
  const double W = p.lambda + w;
  const double mean = (p.lambda * p.prior_mean + s) / W;
  const double su = m[0], sv = m[1], suu = m[2], suv = m[3], svv = m[4];
  // Moments of y about the mean: large absolute altitudes cancel here, not in the solve.
  const double ru = m[5] - mean * su, rv = m[6] - mean * sv;
  // The slopes solve C g = r, C the kernel-weighted scatter of the training offsets about their
  // centroid. Along an eigenvector of C whose spread (eigenvalue / W) is under res^2/12, the
  // spread of a point about its cell centre, the data do not determine a slope: it is 0 there
  // (one cell, or cells on one line, give the kernel mean's height and no slope across).
  const double a = suu - su * su / W, b = suv - su * sv / W, c = svv - sv * sv / W;
  const double floor = p.resolution * p.resolution / 12.0 * W;
  const double half_trace = 0.5 * (a + c);
  const double disc = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  double gu = 0.0, gv = 0.0;
  // The training cells' centroid relative to the cell: how far the intercept is extrapolated.
  const double cu = su / W, cv = sv / W;
  double leverage = 0.0;  // c' C+ c: the intercept's variance beyond sigma2 / W', per sigma2
  for (const double lambda : {half_trace + disc, half_trace - disc}) {
    if (!(lambda >= floor) || !(lambda > 0.0)) continue;
    // An eigenvector of [[a, b], [b, c]] for lambda: the larger of its two candidate forms.
    double eu = b, ev = lambda - a;
    const double fu = lambda - c, fv = b;
    if (fu * fu + fv * fv > eu * eu + ev * ev) eu = fu, ev = fv;
    const double norm2 = eu * eu + ev * ev;
    if (!(norm2 > 0.0)) {  // C = lambda I: every direction is an eigenvector
      gu = ru / lambda;
      gv = rv / lambda;
      leverage = (cu * cu + cv * cv) / lambda;
      break;
    }
    const double t = (eu * ru + ev * rv) / (lambda * norm2);
    gu += t * eu;
    gv += t * ev;
    const double along = (eu * cu + ev * cv);  // the centroid's offset along e, times |e|
    leverage += along * along / (lambda * norm2);
  }
  const double shift = -(su * gu + sv * gv) / W;  // intercept minus mean
  LocalPlane out{mean + shift, gu, gv, 0.0, leverage};
  if (q != 0.0 && w > 0.0) {
    // Sum k (y - h - g.(u, v))^2, expanded in the moments about the mean.
    const double qc = q - s * s / w;
    const double rss = qc - 2.0 * (gu * ru + gv * rv) - W * shift * shift +
                       (suu * gu * gu + 2.0 * suv * gu * gv + svv * gv * gv);
    out.residual = std::max(0.0, rss / w);
  }
  return out;
}

// As ScanIntegrator sums it for its caps; the last parameters' value is kept per thread.
double FullKernelWeight(const MapParams& p) {
  if (!InfersElevation(p.method)) return 1.0;  // raw elevation: one per observation
  thread_local double res = 0.0, l = 0.0, full = 0.0;
  if (p.resolution != res || p.kernel_length != l) {
    const KernelStencil kernel(p.resolution, p.kernel_length);
    full = 0.0;
    for (int r = 0; r < kernel.row_count(); ++r) {
      for (int j = 0; j <= 2 * kernel.half_width(r); ++j) full += kernel.row_weights_double(r)[j];
    }
    res = p.resolution;
    l = p.kernel_length;
  }
  return full;
}

namespace {

// The conditions of the state rule a known cell fails (BlockReason bits), on the estimate's own
// float values so that 0 is exactly "traversable".
uint8_t FailedConditions(const MapParams& p, const CellEstimate& e, double ab, double d) {
  const bool no_value = InfersTraversability(p.method) ? ab == 0.0 : std::isnan(e.traversability);
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
// One seen more than that whose Beta evidence is still thin had it reset again and again (a
// changing place: a new object's edge) and stays blocked. Without dynamics the paper's rule.
CellState StateOf(const MapParams& p, uint8_t reasons, double w) {
  if (reasons == 0) return CellState::kTraversable;
  const bool thin = reasons == kBlockedNoValue || reasons == kBlockedVariance;
  const bool seen_little = w < p.thin_evidence_weight * FullKernelWeight(p);
  return thin && seen_little && p.dynamics == Dynamics::kOn ? CellState::kUnknown
                                                            : CellState::kNonTraversable;
}

}  // namespace

CellEstimate EstimateCell(const MapParams& p, double w, double s, double q, float a, float b,
                          const double* plane) {
  CellEstimate e{kNaN, kNaN, kNaN, kNaN, CellState::kUnknown, static_cast<float>(w), kNaN, 0};
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
    if (plane != nullptr) {
      const LocalPlane fit = FitLocalPlane(p, w, s, dynamic ? q : 0.0, plane);
      if (dynamic) disagreement = fit.residual;
      e.elevation = static_cast<float>(fit.elevation);
      e.elevation_variance =
          static_cast<float>(p.sigma2 * (1.0 / lw + fit.leverage) + disagreement);
    } else {
      if (dynamic) disagreement = Disagreement(w, s, q);
      e.elevation = static_cast<float>((p.lambda * p.prior_mean + s) / lw);
      e.elevation_variance = static_cast<float>(p.sigma2 / lw + disagreement);
    }
    if (dynamic) e.disagreement = static_cast<float>(std::sqrt(disagreement));
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
  e.block_reasons = FailedConditions(p, e, ab, disagreement);
  e.state = StateOf(p, e.block_reasons, w);
  return e;
}

}  // namespace bgkmap
