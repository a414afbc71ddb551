#include "bgkmap/core/vertical_alignment.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {
namespace {

// The median of `v` (the mean of the two middle values for an even count); reorders v.
double Median(std::vector<double>& v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<long>(mid));
  return 0.5 * (lower + upper);
}

}  // namespace

VerticalAlignment AlignScanVertically(const MapParams& p, const PreparedScan& scan,
                                      const MapHeightLookup& map,
                                      const VerticalAlignmentOptions& options) {
  VerticalAlignment a;
  if (!scan.has_sensor) {
    a.outcome = AlignmentOutcome::kNoSensor;
    return a;
  }
  const double min_weight = options.min_map_weight * FullKernelWeight(p);
  const double r2 = options.radius_m * options.radius_m;
  std::vector<double> offsets;
  for (const ObservedCell& c : scan.cells) {
    // The cell's centre, as the map's geometry has it (grid.h: (i + 0.5) res).
    const double dx = (c.cell.x + 0.5) * p.resolution - scan.sensor_x;
    const double dy = (c.cell.y + 0.5) * p.resolution - scan.sensor_y;
    if (dx * dx + dy * dy > r2) continue;
    const MapHeight m = map(c.cell);
    if (!std::isfinite(m.elevation) || !(m.weight >= min_weight) || m.weight <= 0) continue;
    if (options.traversable_only && !m.traversable) continue;
    offsets.push_back(c.y - static_cast<double>(m.elevation));
  }
  a.cells = offsets.size();
  if (offsets.empty()) return a;  // kTooFewCells
  a.median = Median(offsets);
  if (a.cells < options.min_cells) {
    a.outcome = AlignmentOutcome::kTooFewCells;
  } else if (!(std::abs(a.median) <= options.max_offset_m)) {
    a.outcome = AlignmentOutcome::kBeyondBound;
  } else {
    a.outcome = AlignmentOutcome::kAligned;
    a.dz = a.median;
  }
  return a;
}

MapHeightLookup MapHeightsOf(const TerrainMap& map) {
  return [&map](CellIndex cell) {
    const CellEstimate e = map.Estimate(cell);
    return MapHeight{e.elevation, std::isfinite(e.elevation_weight) ? e.elevation_weight : 0.0f,
                     e.state == CellState::kTraversable};
  };
}

Pose AlignedPose(const Pose& pose, const VerticalAlignment& alignment) {
  Pose aligned = pose;
  aligned.translation.z() -= alignment.dz;
  return aligned;
}

}  // namespace bgkmap
