#include "bgkmap/core/cell_estimate.h"

#include <gtest/gtest.h>

#include <cmath>

namespace bgkmap {
namespace {

TEST(CellEstimateTest, UnknownCellIsNaNEverywhere) {
  const CellEstimate e = EstimateCell(MapParams{}, 0.0, 0.0, 0.0, 0.0f, 0.0f);
  EXPECT_EQ(e.state, CellState::kUnknown);
  EXPECT_TRUE(std::isnan(e.elevation));
  EXPECT_TRUE(std::isnan(e.elevation_variance));
  EXPECT_TRUE(std::isnan(e.traversability));
  EXPECT_TRUE(std::isnan(e.traversability_variance));
}

TEST(CellEstimateTest, ElevationFollowsEquation2) {
  MapParams p;
  p.lambda = 0.5;
  p.prior_mean = 1.0;
  p.sigma2 = 0.04;
  // Two observations: y = 2 with k = 1 and y = 4 with k = 0.5: W = 1.5, S = 4.
  const CellEstimate e = EstimateCell(p, 1.5, 4.0, 0.0, 0.0f, 0.0f);
  EXPECT_FLOAT_EQ(e.elevation, (0.5 * 1.0 + 4.0) / (0.5 + 1.5));
  EXPECT_FLOAT_EQ(e.elevation_variance, 0.04 / 2.0);
  EXPECT_FLOAT_EQ(e.elevation_weight, 1.5f);
}

TEST(CellEstimateTest, TraversabilityIsTheBetaPosterior) {
  MapParams p;
  p.alpha0 = 0.5;
  p.beta0 = 1.5;
  // A = 1 (k v summed), B = 3.
  const CellEstimate e = EstimateCell(p, 1.0, 0.0, 0.0, 1.0f, 3.0f);
  const double alpha = 1.5, beta = 4.5, sum = 6.0;
  EXPECT_FLOAT_EQ(e.traversability, alpha / sum);
  // The Beta variance, with the +1 the paper's printed Eq. 4 lacks.
  EXPECT_FLOAT_EQ(e.traversability_variance, alpha * beta / (sum * sum * (sum + 1)));
}

TEST(CellEstimateTest, StateUsesBothThresholds) {
  MapParams p;
  p.dynamics = Dynamics::kOff;  // the paper's rule; with dynamics, see SeenTooLittleIsUnknown
  p.trav_threshold = 0.5;
  p.variance_threshold = 0.05;
  // Well supported and flat: traversable.
  EXPECT_EQ(EstimateCell(p, 10, 0, 0.0, 1.0f, 19.0f).state, CellState::kTraversable);
  // Well supported and rough: not.
  EXPECT_EQ(EstimateCell(p, 10, 0, 0.0, 15.0f, 5.0f).state, CellState::kNonTraversable);
  // Flat but a single weak observation: variance too high, so not traversable.
  const CellEstimate weak = EstimateCell(p, 0.2, 0, 0.0, 0.02f, 0.18f);
  EXPECT_LT(weak.traversability, 0.5f);
  EXPECT_GT(weak.traversability_variance, 0.05f);
  EXPECT_EQ(weak.state, CellState::kNonTraversable);
  // Known elevation without traversability data: the prior decides (mean 0.5): not traversable.
  EXPECT_EQ(EstimateCell(p, 1.0, 0, 0.0, 0.0f, 0.0f).state, CellState::kNonTraversable);
}

TEST(CellEstimateTest, DirectMethodsReportTheStoredValue) {
  MapParams p;
  p.method = Method::kBaseline;
  p.dynamics = Dynamics::kOff;  // with dynamics a cell without a value is unknown (P3)
  const CellEstimate e = EstimateCell(p, 1.0, 0.3, 0.0, 0.25f, 0.75f);
  EXPECT_FLOAT_EQ(e.traversability, 0.25f);
  EXPECT_EQ(e.traversability_variance, 0.0f);
  EXPECT_EQ(e.state, CellState::kTraversable);
  // Observed but too few neighbours for a value: known, conservatively non-traversable.
  const CellEstimate none = EstimateCell(p, 1.0, 0.3, 0.0, 0.0f, 0.0f);
  EXPECT_TRUE(std::isnan(none.traversability));
  EXPECT_EQ(none.state, CellState::kNonTraversable);
}

TEST(CellEstimateTest, LayerNamesRoundTrip) {
  for (int i = 0; i < kLayerCount; ++i) {
    const Layer l = static_cast<Layer>(i);
    Result<Layer> parsed = ParseLayer(LayerName(l));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, l);
  }
  EXPECT_FALSE(ParseLayer("height").ok());
}

TEST(CellEstimateTest, DisagreementEntersVarianceAndStateWithDynamics) {
  // One observation at 1 m and one at 0 m (k = 1 each): W = 2, S = 1, Q = 1, D = 0.25. Beta
  // counts say "clearly traversable".
  MapParams p;
  p.sigma2 = 0.01;
  const CellEstimate on = EstimateCell(p, 2.0, 1.0, 1.0, 0.1f, 19.9f);
  EXPECT_FLOAT_EQ(on.elevation, 0.5f);
  EXPECT_FLOAT_EQ(on.elevation_variance, 0.01 / 2.0 + 0.25);
  EXPECT_EQ(on.state, CellState::kNonTraversable) << "1 m of disagreement is not a drivable cell";

  p.dynamics = Dynamics::kOff;  // the paper: "confidently 0.5 m"
  const CellEstimate off = EstimateCell(p, 2.0, 1.0, 1.0, 0.1f, 19.9f);
  EXPECT_FLOAT_EQ(off.elevation_variance, 0.01 / 2.0);
  EXPECT_EQ(off.state, CellState::kTraversable);

  // Agreement within step_crit stays traversable: y = 0.1 and 0 give D = 0.0025 <= 0.15^2.
  p.dynamics = Dynamics::kOn;
  EXPECT_EQ(EstimateCell(p, 2.0, 0.1, 0.01, 0.1f, 19.9f).state, CellState::kTraversable);
}

// The block reason names each condition of the state rule a cell fails, and is 0 exactly when
// the cell is traversable. Catches: a condition tested with the wrong threshold (each case
// below fails one alone), kBlockedNoValue not reported alone, and a reason on an unknown cell.
TEST(CellEstimateTest, BlockReasonNamesTheFailedConditions) {
  MapParams p;  // bgk+, dynamics on, trav_threshold 0.5, variance_threshold 0.05
  auto reasons = [&](double w, double s, double q, float a, float b) {
    const CellEstimate e = EstimateCell(p, w, s, q, a, b);
    EXPECT_EQ(e.block_reasons == 0,
              e.state == CellState::kTraversable || std::isnan(e.elevation_weight));
    return e.block_reasons;
  };
  EXPECT_EQ(reasons(10.0, 5.0, 2.5, 0.5f, 9.5f), 0);                    // flat, much evidence
  EXPECT_EQ(reasons(0.0, 0.0, 0.0, 0.0f, 0.0f), 0);                     // unknown
  EXPECT_EQ(reasons(1.0, 0.5, 0.25, 0.0f, 0.0f), kBlockedNoValue);      // elevation only
  EXPECT_EQ(reasons(10.0, 5.0, 2.5, 8.0f, 2.0f), kBlockedMean);         // an obstacle
  EXPECT_EQ(reasons(1.0, 0.5, 0.25, 0.05f, 0.3f), kBlockedVariance);    // flat but thin
  EXPECT_EQ(reasons(2.0, 1.0, 1.0, 0.5f, 9.5f), kBlockedDisagreement);  // sqrt(D) = 0.5 m
  EXPECT_EQ(reasons(2.0, 1.0, 1.0, 8.0f, 2.0f), kBlockedMean | kBlockedDisagreement);
  p.dynamics = Dynamics::kOff;  // the paper judges no disagreement
  EXPECT_EQ(reasons(2.0, 1.0, 1.0, 0.5f, 9.5f), 0);
}

// P3 (docs/semantics.md, "Seen too little"): with dynamics, a cell that fails the state rule
// only for want of evidence is unknown, not an obstacle; evidence of an obstacle (the mean, the
// disagreement) still blocks, also when thin; without dynamics the paper's rule blocks all.
// Catches: the rule applied without dynamics, a thin cell with a high mean let through as
// unknown, the disagreement dropped from a no-value cell.
TEST(CellEstimateTest, SeenTooLittleIsUnknown) {
  MapParams p;                                                             // dynamics on
  const CellEstimate thin = EstimateCell(p, 1.0, 0.5, 0.25, 0.05f, 0.3f);  // mean 0.14, var 0.08
  EXPECT_EQ(thin.state, CellState::kUnknown);
  EXPECT_EQ(thin.block_reasons, kBlockedVariance);
  EXPECT_FLOAT_EQ(thin.elevation, 0.5f);  // its elevation is known all the same
  const CellEstimate no_value = EstimateCell(p, 1.0, 0.5, 0.25, 0.0f, 0.0f);
  EXPECT_EQ(no_value.state, CellState::kUnknown);
  EXPECT_EQ(no_value.Get(Layer::kBlockReason), static_cast<float>(kBlockedNoValue));
  // Thin evidence of an obstacle: blocked (mean 0.86 with variance 0.08).
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.3f, 0.05f).state, CellState::kNonTraversable);
  // No traversability value but observations 1 m apart: blocked.
  const CellEstimate split = EstimateCell(p, 2.0, 1.0, 1.0, 0.0f, 0.0f);
  EXPECT_EQ(split.state, CellState::kNonTraversable);
  EXPECT_EQ(split.block_reasons, kBlockedNoValue | kBlockedDisagreement);
  // P3': seen more than thin_evidence_weight (0.5) full-kernel observations (3.8955 at 0.1 m
  // cells, l = 0.3 m) and still thin: its Beta evidence was reset again and again (a changing
  // place), blocked. Catches the weight condition dropped or taken against the wrong sum.
  EXPECT_EQ(EstimateCell(p, 1.9, 0.95, 0.475, 0.0f, 0.0f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 2.0, 1.0, 0.5, 0.0f, 0.0f).state, CellState::kNonTraversable);
  // Thin ground (the variance alone, the mean leaning traversable) is unknown however much it
  // was seen with the default thin_ground_weight (100: above the confidence cap of 20
  // full-kernel observations); with thin_ground_weight 1, unknown below one full-kernel
  // observation and blocked from it on. Catches the ground weight applied to a cell without a
  // value, or not applied.
  EXPECT_EQ(EstimateCell(p, 2.0, 1.0, 0.5, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 3.9, 1.95, 0.975, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 77.9, 38.95, 19.475, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 77.9, 38.95, 19.475, 0.0f, 0.0f).state, CellState::kNonTraversable);
  p.thin_ground_weight = 1.0;
  EXPECT_EQ(EstimateCell(p, 3.8, 1.9, 0.95, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 3.9, 1.95, 0.975, 0.05f, 0.3f).state, CellState::kNonTraversable);
  p.thin_ground_weight = 0.25;  // less than thin_evidence_weight: the larger holds
  EXPECT_EQ(EstimateCell(p, 1.9, 0.95, 0.475, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 2.0, 1.0, 0.5, 0.05f, 0.3f).state, CellState::kNonTraversable);
  p.thin_ground_weight = 1.0;
  p.thin_evidence_weight = 0.0;  // thin ground still unknown below its own weight
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.05f, 0.3f).state, CellState::kUnknown);
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.0f, 0.0f).state, CellState::kNonTraversable);
  p.thin_ground_weight = 0.0;  // both off: the paper's state
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.05f, 0.3f).state, CellState::kNonTraversable);
  p.thin_evidence_weight = 0.5;
  p.thin_ground_weight = 1.0;
  p.dynamics = Dynamics::kOff;
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.05f, 0.3f).state, CellState::kNonTraversable);
  EXPECT_EQ(EstimateCell(p, 1.0, 0.5, 0.25, 0.0f, 0.0f).state, CellState::kNonTraversable);
}

// The explanation layers through CellEstimate::Get: the disagreement in metres (NaN without
// dynamics, where the map keeps no Q, and without weight), the reason as a number (NaN where
// unknown, 0 where traversable).
TEST(CellEstimateTest, ExplanationLayers) {
  MapParams p;
  const CellEstimate e = EstimateCell(p, 2.0, 1.0, 1.0, 8.0f, 2.0f);  // D = 0.25
  EXPECT_FLOAT_EQ(e.Get(Layer::kDisagreement), 0.5f);
  EXPECT_EQ(e.Get(Layer::kBlockReason), static_cast<float>(kBlockedMean | kBlockedDisagreement));
  EXPECT_EQ(EstimateCell(p, 10.0, 5.0, 2.5, 0.5f, 9.5f).Get(Layer::kBlockReason), 0.0f);
  EXPECT_TRUE(std::isnan(EstimateCell(p, 0.0, 0.0, 0.0, 0.0f, 0.0f).Get(Layer::kBlockReason)));
  EXPECT_TRUE(std::isnan(EstimateCell(p, 0.0, 0.0, 0.0, 1.0f, 1.0f).Get(Layer::kDisagreement)));
  p.dynamics = Dynamics::kOff;
  EXPECT_TRUE(std::isnan(EstimateCell(p, 2.0, 1.0, 1.0, 8.0f, 2.0f).Get(Layer::kDisagreement)));
}

}  // namespace
}  // namespace bgkmap
