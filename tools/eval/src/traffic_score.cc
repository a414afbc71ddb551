#include "bgkmap/eval/traffic_score.h"

#include <algorithm>
#include <cmath>

#include "bgkmap/eval/drive_score.h"

namespace bgkmap::eval {
namespace {

using CellSet = std::vector<CellIndex>;  // sorted, unique

bool In(const CellSet& s, CellIndex c) { return std::binary_search(s.begin(), s.end(), c); }

// Whether `cell` is traversable in the truth (NaN: not judged).
bool TrulyTraversable(const Raster& truth, const std::vector<float>& state, CellIndex c) {
  if (!truth.box.Contains(c)) return false;
  const size_t k =
      static_cast<size_t>(truth.box.max.y - c.y) * truth.cols + (c.x - truth.box.min.x);
  return state[k] == static_cast<float>(CellState::kTraversable);
}

double Share(int64_t part, int64_t whole) {
  return whole ? static_cast<double>(part) / static_cast<double>(whole) : NAN;
}

}  // namespace

double TrafficCounts::stale_rate() const { return Share(trail_stale, trail_judged); }
double TrafficCounts::missed_rate() const { return Share(new_missed, new_judged); }
double VehicleCounts::stale_rate() const { return Share(trail_stale, trail_judged); }
double VehicleCounts::missed_rate() const { return Share(new_missed, new_judged); }

std::vector<CellIndex> CellsNearBox(const GridGeometry& g, const std::array<double, 4>& b,
                                    double radius) {
  std::vector<CellIndex> out;
  const CellBox box = g.BoxCovering(b[0] - radius, b[1] - radius, b[2] + radius, b[3] + radius);
  for (int iy = box.min.y; iy <= box.max.y; ++iy) {
    for (int ix = box.min.x; ix <= box.max.x; ++ix) {
      const double x = g.CellCenterX(ix), y = g.CellCenterY(iy);
      const double dx = std::max({b[0] - x, 0.0, x - b[2]});
      const double dy = std::max({b[1] - y, 0.0, y - b[3]});
      if (dx * dx + dy * dy <= radius * radius * (1 + 1e-9)) out.push_back({ix, iy});
    }
  }
  return out;
}

TrafficJudge::TrafficJudge(const MapParams& params, const std::vector<VehicleTrack>& tracks,
                           int scans, const Raster& static_truth,
                           const std::vector<std::vector<CellIndex>>& observed, int trail_scans,
                           int new_scans)
    : due_(static_cast<size_t>(std::max(scans, 0))) {
  const GridGeometry g(params.resolution, params.tile_size);
  counts_.by_vehicle.resize(tracks.size());
  // The cells the vehicles occupy at each scan, all of them and each vehicle's.
  std::vector<CellSet>& occupied = occupied_;
  occupied.resize(due_.size());
  near_.resize(due_.size());
  std::vector<std::vector<CellSet>> occupied_by(tracks.size(), std::vector<CellSet>(due_.size()));
  for (size_t v = 0; v < tracks.size(); ++v) {
    const VehicleTrack& t = tracks[v];
    for (size_t i = 0; i < t.boxes.size(); ++i) {
      const int k = t.first_scan + static_cast<int>(i);
      if (k < 0 || k >= scans) continue;
      occupied_by[v][k] = CellsNearBox(g, t.boxes[i], params.robot_radius);
      occupied[k].insert(occupied[k].end(), occupied_by[v][k].begin(), occupied_by[v][k].end());
      for (const CellIndex& c :
           CellsNearBox(g, t.boxes[i], params.robot_radius + params.kernel_length))
        near_[k].push_back(c);
    }
  }
  for (std::vector<CellSet>* sets : {&occupied, &near_}) {
    for (CellSet& s : *sets) {
      std::sort(s.begin(), s.end());
      s.erase(std::unique(s.begin(), s.end()), s.end());
    }
  }
  const std::vector<float>* state = static_truth.Find(Layer::kState);
  if (state == nullptr) return;
  for (std::vector<CellSet>& per_scan : occupied_by) {
    for (CellSet& s : per_scan) std::sort(s.begin(), s.end());  // CellsNearBox: no repeats
  }
  auto vehicle_at = [&](int k, CellIndex c) {
    for (size_t v = 0; v < occupied_by.size(); ++v) {
      if (In(occupied_by[v][k], c)) return static_cast<int>(v);
    }
    return -1;  // not reached: c is in occupied[k]
  };
  auto seen_in = [&](CellIndex c, int from, int to) {
    for (int m = from; m <= to; ++m) {
      if (m < static_cast<int>(observed.size()) && In(observed[m], c)) return true;
    }
    return false;
  };
  for (int k = 1; k < scans; ++k) {
    // Left at k: occupied at k - 1, not at k; judged at k + trail_scans - 1 if still free.
    const int trail_at = k + trail_scans - 1;
    for (const CellIndex& c : occupied[k - 1]) {
      if (In(occupied[k], c) || trail_at >= scans) continue;
      bool free = true;
      for (int m = k + 1; m <= trail_at && free; ++m) free = !In(occupied[m], c);
      if (free && TrulyTraversable(static_truth, *state, c) && seen_in(c, k, trail_at))
        due_[trail_at].push_back({c, true, vehicle_at(k - 1, c)});
    }
    // Entered at k: occupied at k, not at k - 1; judged at k + new_scans - 1 if still occupied.
    const int new_at = k + new_scans - 1;
    for (const CellIndex& c : occupied[k]) {
      if (In(occupied[k - 1], c) || new_at >= scans) continue;
      bool still = true;
      for (int m = k + 1; m <= new_at && still; ++m) still = In(occupied[m], c);
      if (still && TrulyTraversable(static_truth, *state, c) && seen_in(c, k, new_at))
        due_[new_at].push_back({c, false, vehicle_at(k, c)});
    }
  }
}

bool TrafficJudge::Occupied(int k, CellIndex cell) const {
  return k >= 0 && k < static_cast<int>(occupied_.size()) && In(occupied_[k], cell);
}

bool TrafficJudge::Near(int k, CellIndex cell) const {
  return k >= 0 && k < static_cast<int>(near_.size()) && In(near_[k], cell);
}

void TrafficJudge::Score(int k, const TerrainMap& map) {
  if (k < 0 || k >= static_cast<int>(due_.size())) return;
  for (const Due& d : due_[k]) {
    const CellState s = map.Estimate(d.cell).state;
    VehicleCounts& by = counts_.by_vehicle[static_cast<size_t>(d.vehicle)];
    if (d.trail) {
      ++counts_.trail_judged;
      ++by.trail_judged;
      if (s != CellState::kNonTraversable) continue;
      ++counts_.trail_stale;
      ++by.trail_stale;
      const uint8_t r = BlockReasonsAt(map, d.cell);
      counts_.stale_no_value += (r & kNoValue) != 0;
      counts_.stale_mean += (r & kHighMean) != 0;
      counts_.stale_variance += (r & kHighVariance) != 0;
      counts_.stale_disagreement += (r & kDisagreement) != 0;
    } else {
      ++counts_.new_judged;
      ++by.new_judged;
      counts_.new_missed += s != CellState::kNonTraversable;
      by.new_missed += s != CellState::kNonTraversable;
      counts_.new_unknown += s == CellState::kUnknown;
    }
  }
}

}  // namespace bgkmap::eval
