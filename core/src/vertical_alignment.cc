#include "bgkmap/core/vertical_alignment.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
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

// One compared cell: its offset from the sensor and its height's offset from the map.
struct Residual {
  double dx, dy, r;
};

// The tilt of the residuals' plane r = a + gx dx + gy dy, fitted by least squares on the cells
// within `band` of `median`; false if they are too few, do not spread in both directions, or
// the slope exceeds `max_slope`.
bool FitTilt(const std::vector<Residual>& cells, double median, double band, double max_slope,
             size_t min_cells, double* gx, double* gy) {
  Eigen::Matrix3d n = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  size_t used = 0;
  for (const Residual& c : cells) {
    if (std::abs(c.r - median) > band) continue;
    const Eigen::Vector3d row(1.0, c.dx, c.dy);
    n += row * row.transpose();
    rhs += row * c.r;
    ++used;
  }
  if (used < min_cells) return false;
  Eigen::LDLT<Eigen::Matrix3d> ldlt(n);
  // Cells on one line through the sensor (a corridor) do not fix the slope across it.
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9)) return false;
  const Eigen::Vector3d plane = ldlt.solve(rhs);
  if (!(std::abs(plane[1]) <= max_slope && std::abs(plane[2]) <= max_slope)) return false;
  *gx = plane[1];
  *gy = plane[2];
  return true;
}

// With options.max_tilt_deg > 0: the tilt of `cells`' residuals, and the median offset once the
// tilt is taken out (stored in a).
void EstimateTilt(const VerticalAlignmentOptions& options, std::vector<Residual>& cells,
                  VerticalAlignment* a) {
  const double max_slope = std::tan(options.max_tilt_deg * std::numbers::pi / 180.0);
  double gx = 0, gy = 0;
  if (!FitTilt(cells, a->median, options.tilt_inlier_m, max_slope, options.min_cells, &gx, &gy))
    return;
  std::vector<double> level;
  level.reserve(cells.size());
  for (const Residual& c : cells) level.push_back(c.r - gx * c.dx - gy * c.dy);
  const double dz = Median(level);
  if (!(std::abs(dz) <= options.max_offset_m)) return;
  a->dz = dz;
  a->slope_x = gx;
  a->slope_y = gy;
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
  std::vector<Residual> residuals;
  for (const ObservedCell& c : scan.cells) {
    // The cell's centre, as the map's geometry has it (grid.h: (i + 0.5) res).
    const double dx = (c.cell.x + 0.5) * p.resolution - scan.sensor_x;
    const double dy = (c.cell.y + 0.5) * p.resolution - scan.sensor_y;
    if (dx * dx + dy * dy > r2) continue;
    const MapHeight m = map(c.cell);
    if (!std::isfinite(m.elevation) || !(m.weight >= min_weight) || m.weight <= 0) continue;
    if (options.traversable_only && !m.traversable) continue;
    offsets.push_back(c.y - static_cast<double>(m.elevation));
    if (options.max_tilt_deg > 0) residuals.push_back({dx, dy, offsets.back()});
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
    if (options.max_tilt_deg > 0) EstimateTilt(options, residuals, &a);
  }
  return a;
}

double VerticalAlignment::TiltDegrees() const {
  return std::atan(std::max(std::abs(slope_x), std::abs(slope_y))) * 180.0 / std::numbers::pi;
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
  if (alignment.Levelled()) {
    // Turn the scan about the sensor so that its heights fall by slope_x dx + slope_y dy: about
    // the map's y axis by atan(slope_x) (z' = z - sin(a) x) and its x axis by -atan(slope_y).
    const Eigen::Matrix3d level =
        (Eigen::AngleAxisd(-std::atan(alignment.slope_y), Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(std::atan(alignment.slope_x), Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    aligned.rotation = level * pose.rotation;
  }
  return aligned;
}

}  // namespace bgkmap
