// Receiver operating characteristic of a score against binary labels (paper Fig. 5): the
// positive class is "non-traversable" and the score is the predicted traversability value, so
// the curve does not depend on the threshold of Eq. 6.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace bgkmap::eval {

struct RocPoint {
  double fpr = 0;  // false-positive rate
  double tpr = 0;  // true-positive rate
};

struct Roc {
  std::vector<RocPoint> curve;  // from (0,0) to (1,1), one point per distinct score
  double auc = 0;               // NaN if a class is missing
  int64_t positives = 0;
  int64_t negatives = 0;
};

// Higher score = more likely positive. Tied scores form one step of the curve (a diagonal
// segment), so the AUC equals the Mann-Whitney probability with ties counted as 1/2.
Roc ComputeRoc(std::span<const double> scores, std::span<const uint8_t> positive);

// At most `max_points` points of the curve, always keeping both ends (for plotting).
std::vector<RocPoint> Thin(const std::vector<RocPoint>& curve, size_t max_points);

}  // namespace bgkmap::eval
