#include "bgkmap/eval/scan_truth.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace bgkmap::eval {

ScanTruthBuilder::ScanTruthBuilder(const MapParams& params, ScanTruthOptions options)
    : params_(params), prepare_params_(params), options_(options) {
  // The footprint (sensor_height > 0 with dynamics on) is evidence the map may add, not a point:
  // the truth is made of returns only. No filter depends on it.
  prepare_params_.sensor_height = 0.0;
}

Status ScanTruthBuilder::AddScan(std::span<const Point3f> points, const Pose& T_map_sensor,
                                 bool frame_is_map) {
  if (Status s = ValidatePose(T_map_sensor, params_); !s.ok()) return s;
  // Each point is prepared alone: PrepareScan then tells whether the mapping filters keep it,
  // its cell and its map-frame height (a one-point cell's training value under either rule),
  // which lets the truth pool points across scans and count them.
  std::vector<std::pair<CellIndex, double>> kept;
  kept.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    Result<PreparedScan> one =
        PrepareScan(prepare_params_, points.subspan(i, 1), T_map_sensor, frame_is_map);
    if (!one.ok()) return one.status();
    for (const ObservedCell& oc : one->cells) kept.emplace_back(oc.cell, oc.y);
  }
  for (const auto& [cell, z] : kept) {
    Cell& c = cells_[Key(cell)];
    c.max = c.count == 0 ? z : std::max(c.max, z);
    c.sum += z;
    ++c.count;
  }
  ++scans_;
  input_ += points.size();
  kept_ += kept.size();
  return Status::Ok();
}

CellHeights ScanTruthBuilder::Surface() const {
  const uint32_t min_points = static_cast<uint32_t>(std::max(options_.min_points, 1));
  auto cell_of = [](uint64_t key) {
    return CellIndex{static_cast<int>(static_cast<uint32_t>(key >> 32)),
                     static_cast<int>(static_cast<uint32_t>(key & 0xffffffffu))};
  };
  CellBox box;
  for (const auto& [key, c] : cells_) {
    if (c.count >= min_points) box.Extend(cell_of(key));
  }
  CellHeights surface(box);
  for (const auto& [key, c] : cells_) {
    if (c.count < min_points) continue;
    surface.set(cell_of(key), params_.observation == Observation::kMax ? c.max : c.sum / c.count);
  }
  return surface;
}

Raster ScanTruthBuilder::Build() const {
  const CellHeights surface = Surface();
  return TruthFromHeights(
      surface, surface.box, params_, [](CellIndex) { return true; }, SparseNeighbourhood::kUnknown);
}

ScanTruthStats ScanTruthBuilder::Stats(const Raster& truth) const {
  ScanTruthStats s;
  s.scans = scans_;
  s.points_input = input_;
  s.points_kept = kept_;
  s.observed_cells = static_cast<int64_t>(cells_.size());
  const uint32_t min_points = static_cast<uint32_t>(std::max(options_.min_points, 1));
  for (const auto& [key, c] : cells_) s.supported_cells += c.count >= min_points ? 1 : 0;
  const std::vector<float>* state = truth.Find(Layer::kState);
  if (state == nullptr) return s;
  for (float v : *state) {
    if (std::isnan(v)) continue;
    ++s.judged_cells;
    if (static_cast<CellState>(static_cast<int>(v)) == CellState::kTraversable) {
      ++s.traversable_cells;
    } else {
      ++s.non_traversable_cells;
    }
  }
  return s;
}

}  // namespace bgkmap::eval
