#include "bgkmap/eval/roc.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace bgkmap::eval {

Roc ComputeRoc(std::span<const double> scores, std::span<const uint8_t> positive) {
  Roc roc;
  const size_t n = std::min(scores.size(), positive.size());
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return scores[a] > scores[b]; });
  for (size_t i = 0; i < n; ++i) (positive[i] ? roc.positives : roc.negatives)++;
  roc.curve.push_back({0, 0});
  if (roc.positives == 0 || roc.negatives == 0) {
    roc.auc = std::numeric_limits<double>::quiet_NaN();
    return roc;
  }
  int64_t tp = 0, fp = 0;
  double area = 0;
  for (size_t i = 0; i < n;) {
    const int64_t tp0 = tp, fp0 = fp;
    const double s = scores[order[i]];
    for (; i < n && scores[order[i]] == s; ++i) (positive[order[i]] ? tp : fp)++;
    area += static_cast<double>(fp - fp0) * 0.5 * static_cast<double>(tp + tp0);  // trapezoid
    roc.curve.push_back(
        {static_cast<double>(fp) / roc.negatives, static_cast<double>(tp) / roc.positives});
  }
  roc.auc = area / (static_cast<double>(roc.positives) * static_cast<double>(roc.negatives));
  return roc;
}

std::vector<RocPoint> Thin(const std::vector<RocPoint>& curve, size_t max_points) {
  if (curve.size() <= max_points || max_points < 2) return curve;
  std::vector<RocPoint> out;
  for (size_t i = 0; i < max_points; ++i) {
    out.push_back(curve[i * (curve.size() - 1) / (max_points - 1)]);
  }
  return out;
}

}  // namespace bgkmap::eval
