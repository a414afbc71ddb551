#include "bgkmap/eval/map_score.h"

#include <cmath>

namespace bgkmap::eval {

MapScore ScoreMap(const TerrainMap& map, const Raster& truth) {
  MapScore s;
  const std::vector<float>* elevation = truth.Find(Layer::kElevation);
  const std::vector<float>* state = truth.Find(Layer::kState);
  if (elevation == nullptr || state == nullptr) return s;
  std::vector<double> scores;
  std::vector<uint8_t> positive;
  double se_all = 0, se_ground = 0;
  int64_t n_all = 0, agree = 0;
  for (int64_t row = 0; row < truth.rows; ++row) {
    for (int64_t col = 0; col < truth.cols; ++col) {
      const size_t k = static_cast<size_t>(row * truth.cols + col);
      if (std::isnan((*state)[k])) continue;
      ++s.truth_cells;
      const CellIndex cell{truth.box.min.x + static_cast<int>(col),
                           truth.box.max.y - static_cast<int>(row)};
      const CellEstimate e = map.Estimate(cell);
      if (e.state == CellState::kUnknown) continue;
      ++s.known_cells;
      const auto truth_state = static_cast<CellState>(static_cast<int>((*state)[k]));
      const bool blocked = truth_state == CellState::kNonTraversable;
      if (std::isfinite(e.elevation)) {
        const double d = static_cast<double>(e.elevation) - (*elevation)[k];
        se_all += d * d;
        ++n_all;
        if (!blocked) {
          se_ground += d * d;
          ++s.ground_cells;
        }
      }
      scores.push_back(std::isnan(e.traversability) ? 1.0 : e.traversability);
      positive.push_back(blocked ? 1 : 0);
      agree += (e.state == truth_state);
      const bool called_traversable = e.state == CellState::kTraversable;
      s.dangerous_misses += (blocked && called_traversable);
      s.false_alarms += (!blocked && !called_traversable);
    }
  }
  const double nan = std::nan("");
  s.coverage = s.truth_cells ? static_cast<double>(s.known_cells) / s.truth_cells : nan;
  s.mse_all = n_all ? se_all / n_all : nan;
  s.mse_ground = s.ground_cells ? se_ground / s.ground_cells : nan;
  s.state_accuracy = s.known_cells ? static_cast<double>(agree) / s.known_cells : nan;
  s.dangerous_miss_rate =
      s.known_cells ? static_cast<double>(s.dangerous_misses) / s.known_cells : nan;
  s.false_alarm_rate = s.known_cells ? static_cast<double>(s.false_alarms) / s.known_cells : nan;
  s.roc = ComputeRoc(scores, positive);
  return s;
}

}  // namespace bgkmap::eval
