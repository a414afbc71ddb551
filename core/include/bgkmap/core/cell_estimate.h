// Derived layers: what a planner reads from a cell's statistics (paper Eqs. 2, 4, 6).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string_view>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

enum class CellState : uint8_t { kUnknown = 0, kTraversable = 1, kNonTraversable = 2 };

// The derived layers a query can ask for. The numeric values are stable (used in files).
enum class Layer : uint8_t {
  kElevation = 0,
  kElevationVariance = 1,
  kTraversability = 2,
  kTraversabilityVariance = 3,
  kState = 4,
  kElevationWeight = 5,  // W, the kernel-weighted observation count behind the elevation
  kDisagreement = 6,     // sqrt(D), metres: how far the cell's observations disagree (dynamics)
  kBlockReason = 7,      // why a known cell is non-traversable: BlockReason bits, 0 = traversable
};
inline constexpr int kLayerCount = 8;
std::string_view LayerName(Layer layer);
Result<Layer> ParseLayer(std::string_view name);

// Why a known cell is non-traversable: the conditions of the state rule below that it fails
// (docs/semantics.md, "Why a cell is blocked"). A cell may fail several. kBlockedNoValue (no
// traversability evidence at all, only elevation) is reported alone: the prior's mean and
// variance then fail the others by construction. kBlockedMean is evidence of an obstacle;
// kBlockedVariance alone is evidence too thin to call the cell traversable.
enum BlockReason : uint8_t {
  kBlockedNoValue = 1,       // A + B = 0 (a Beta method) or no direct value
  kBlockedMean = 2,          // traversability mean (+ bgk-obstacle's margin) >= trav_threshold
  kBlockedVariance = 4,      // traversability variance >= variance_threshold
  kBlockedDisagreement = 8,  // sqrt(D) > step_crit (dynamics on)
};

// NaN marks "unknown" in every float layer.
struct CellEstimate {
  static constexpr float kUnknownFloat = std::numeric_limits<float>::quiet_NaN();

  float elevation;
  float elevation_variance;
  float traversability;  // 0 = flat and smooth ... 1 = non-traversable
  float traversability_variance;
  CellState state;
  float elevation_weight;
  float disagreement;     // sqrt of what the state rule judges; NaN without weight or dynamics
  uint8_t block_reasons;  // BlockReason bits: the conditions failed; 0 = traversable or none

  // Inline: a loop over the layers of many cells folds the switch away (raster.cc).
  float Get(Layer layer) const {
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
        return std::isnan(elevation_weight) ? kUnknownFloat : static_cast<float>(block_reasons);
    }
    return kUnknownFloat;
  }
};

// Computes the derived layers of one cell from its statistics.
//  elevation = (lambda mu0 + S) / (lambda + W), variance = sigma2 / (lambda + W), if W > 0.
//  traversability (inferring methods): alpha = alpha0 + A, beta = beta0 + B,
//    mean = alpha / (alpha + beta), variance = alpha beta / ((alpha + beta)^2 (alpha + beta + 1)).
//  traversability (direct methods): mean = A / (A + B), the latest computed v; variance 0.
//  state: unknown if not known; traversable if mean < trav_threshold and variance <
//    variance_threshold; otherwise non-traversable (also when the mean is undefined).
// With dynamics on, the observations' disagreement D = Q/W - (S/W)^2 (their kernel-weighted
// variance) is added to the elevation variance, and a cell whose observations disagree by more
// than a step the robot can take (sqrt(D) > step_crit) is non-traversable; one that fails only
// for want of evidence (kBlockedNoValue or kBlockedVariance alone) with W < thin_evidence_weight
// FullKernelWeight(p) is unknown, seen too little; failing the variance alone, also with
// W < thin_ground_weight FullKernelWeight(p) (by default above the confidence cap: always).
// bgk-ll: `plane` holds the cell's Tile::kPlaneMoments plane moments (Tile::PlaneOf), and the
// elevation is the intercept of the local plane fit (FitLocalPlane) instead of the kernel mean;
// the disagreement is the fit's residual instead of the spread around the mean; the elevation
// variance is sigma2 (1 / (lambda + W) + leverage) plus the disagreement.
CellEstimate EstimateCell(const MapParams& p, double w, double s, double q, float a, float b,
                          const double* plane = nullptr);

// The kernel-weighted plane z = h + g_u u + g_v v through a cell's neighbourhood (bgk-ll,
// docs/semantics.md): weighted least squares on the moments, with the prior (lambda, mu0) as a
// pseudo-observation at the cell. Where the training cells spread less than res^2/12 (a point's
// spread about its cell centre) in some direction, there is no slope along it: one cell gives
// the kernel mean, cells on one line a slope along the line only. Data on a plane give that
// plane exactly. `residual` is the plane's weighted mean squared residual from Q (0 without
// dynamics).
struct LocalPlane {
  double elevation;
  double slope_u, slope_v;
  double residual;
  // c' C+ c, c the training cells' weighted centroid relative to the cell: the intercept's
  // variance is sigma2 (1 / W' + leverage), large where the plane is extrapolated (a cell at the
  // fringe of what was seen, its data all on one side).
  double leverage;
};
LocalPlane FitLocalPlane(const MapParams& p, double w, double s, double q, const double* plane);

// The weight one full-kernel observation (every cell within l observed once) gives a cell: the
// unit of max_confidence_scans and thin_evidence_weight; 1 for the raw-elevation methods.
double FullKernelWeight(const MapParams& p);

// D = Q/W - (S/W)^2, clamped at 0 against rounding; 0 without weight.
double Disagreement(double w, double s, double q);

}  // namespace bgkmap
