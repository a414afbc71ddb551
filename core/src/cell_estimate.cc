#include "bgkmap/core/cell_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "bgkmap/core/sparse_kernel.h"
#include "cell_estimate_inline.h"

namespace bgkmap {
namespace {
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

double Disagreement(double w, double s, double q) { return internal::DisagreementOf(w, s, q); }

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

CellEstimate EstimateCell(const MapParams& p, double w, double s, double q, float a, float b,
                          const double* plane) {
  return internal::EstimateCellWith(p, internal::EstimateConstants::Of(p), w, s, q, a, b, plane);
}

}  // namespace bgkmap
