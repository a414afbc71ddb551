#include "bgkmap/core/scan.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "bgkmap/core/cell_shapes.h"
#include "bgkmap/core/point_filter.h"
#include "radix_sort.h"
#include "scan_reach.h"
#include "scratch_buffer.h"

namespace bgkmap {

Pose Pose::FromQuaternion(double qw, double qx, double qy, double qz, double tx, double ty,
                          double tz) {
  Pose p;
  p.rotation = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix();
  p.translation = {tx, ty, tz};
  return p;
}

Status ValidatePose(const Pose& pose, const MapParams& params) {
  if (!pose.rotation.allFinite() || !pose.translation.allFinite()) {
    return Status::InvalidArgument("pose: every entry must be finite");
  }
  const double ortho = (pose.rotation.transpose() * pose.rotation - Eigen::Matrix3d::Identity())
                           .cwiseAbs()
                           .maxCoeff();
  const double det = pose.rotation.determinant();
  if (ortho > kRotationTolerance || std::abs(det - 1.0) > kRotationTolerance) {
    std::ostringstream os;
    os << "pose: rotation is not orthonormal (max |R^T R - I| = " << ortho << ", det = " << det
       << "; tolerance " << kRotationTolerance << ")";
    return Status::InvalidArgument(os.str());
  }
  const double limit = kMaxCellIndex * params.resolution;
  if (pose.translation.head<2>().cwiseAbs().maxCoeff() >= limit ||
      std::abs(pose.translation.z()) >= limit) {
    std::ostringstream os;
    os << "pose: translation (" << pose.translation.transpose() << ") exceeds the map's "
       << "coordinate range +-" << limit << " m";
    return Status::OutOfRange(os.str());
  }
  return Status::Ok();
}

namespace {

struct BinnedPoint {
  int ix, iy;
  double z;
};

// The scan's binned points and their sort keys, kept per thread (scratch_buffer.h).
thread_local std::vector<BinnedPoint> binned_points;
thread_local std::vector<uint64_t> binned_keys;
const bool kKeptBins = internal::RegisterKeptScratch(
    {[] {
       std::vector<BinnedPoint>().swap(binned_points);
       std::vector<uint64_t>().swap(binned_keys);
     },
     [] { return internal::CapacityBytes(binned_points) + internal::CapacityBytes(binned_keys); }});

// Reduces points sorted by cell into one observation per cell.
std::vector<ObservedCell> ReduceCells(const std::vector<BinnedPoint>& pts,
                                      const std::vector<uint32_t>& order, Observation mode) {
  std::vector<ObservedCell> cells;
  size_t i = 0;
  while (i < order.size()) {
    const BinnedPoint& first = pts[order[i]];
    double best = first.z, low = first.z, sum = 0.0;
    size_t j = i;
    for (; j < order.size(); ++j) {
      const BinnedPoint& p = pts[order[j]];
      if (p.ix != first.ix || p.iy != first.iy) break;
      best = std::max(best, p.z);
      low = std::min(low, p.z);
      sum += p.z;
    }
    const double y = mode == Observation::kMax ? best : sum / static_cast<double>(j - i);
    const double span_mm = std::min(65535.0, std::floor((best - low) * 1000.0));
    cells.push_back({{first.ix, first.iy}, y, static_cast<uint16_t>(span_mm)});
    i = j;
  }
  return cells;
}

}  // namespace

std::vector<TileKey> PreparedScan::ChangeableTiles() const {
  std::vector<TileKey> out;
  out.reserve(write_tiles.size() + clear_tiles.size());
  std::merge(write_tiles.begin(), write_tiles.end(), clear_tiles.begin(), clear_tiles.end(),
             std::back_inserter(out));
  return out;
}

namespace {

// Filters and transforms the points, and bins the kept ones into `binned` (semantics 1-2); fills
// `counts` and the kept points' cell bounds.
void TransformAndBin(const MapParams& params, std::span<const Point3f> points, const Pose& T,
                     bool frame_is_map, ScanPointCounts& c, CellBox& bounds,
                     std::vector<BinnedPoint>& binned) {
  c.input = points.size();
  const double min_r2 = params.min_range * params.min_range;
  const double max_r2 = params.max_range * params.max_range;
  const double inv_res = 1.0 / params.resolution;
  const double z_limit = T.translation.z() + params.max_height_above_sensor;
  const bool self_filter = !frame_is_map && SelfFilterOn(params);
  binned.clear();
  binned.reserve(points.size());
  for (const Point3f& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      ++c.dropped_nonfinite;
      continue;
    }
    const Eigen::Vector3d ps(p.x, p.y, p.z);
    if (!frame_is_map) {
      const double r2 = ps.squaredNorm();
      if (r2 < min_r2 || r2 > max_r2 || (self_filter && InSelfFilterBox(params, ps))) {
        ++c.dropped_range;
        continue;
      }
    }
    const Eigen::Vector3d q = T.rotation * ps + T.translation;
    if (!frame_is_map && q.z() > z_limit) {
      ++c.dropped_height;
      continue;
    }
    const double fx = std::floor(q.x() * inv_res);
    const double fy = std::floor(q.y() * inv_res);
    if (!(std::abs(fx) <= kMaxCellIndex && std::abs(fy) <= kMaxCellIndex &&
          std::abs(q.z()) < kMaxCellIndex * params.resolution)) {
      ++c.dropped_out_of_bounds;
      continue;
    }
    const BinnedPoint b{static_cast<int>(fx), static_cast<int>(fy), q.z()};
    bounds.Extend({b.ix, b.iy});
    binned.push_back(b);
  }
  c.kept = binned.size();
}

// The vehicle's box (footprint_length x footprint_width) under a sensor at `t`, turned to the
// sensor's heading (its x axis on the map's xy plane; east if it points straight up or down),
// the sensor at (footprint_sensor_x, footprint_sensor_y) from the box's centre.
std::vector<CellIndex> FootprintBoxCells(const MapParams& p, const GridGeometry& grid,
                                         const Pose& T) {
  const Eigen::Vector3d ax = T.rotation.col(0);
  const double norm = std::hypot(ax.x(), ax.y());
  const double c = norm > 1e-9 ? ax.x() / norm : 1.0, s = norm > 1e-9 ? ax.y() / norm : 0.0;
  const Eigen::Vector3d& t = T.translation;
  auto place = [&](double u, double v) {  // box frame (centre, x forward) to map
    const double bu = u - p.footprint_sensor_x, bv = v - p.footprint_sensor_y;
    return Point2{t.x() + c * bu - s * bv, t.y() + s * bu + c * bv};
  };
  const double hl = 0.5 * p.footprint_length, hw = 0.5 * p.footprint_width;
  const Point2 corners[] = {place(hl, hw), place(-hl, hw), place(-hl, -hw), place(hl, -hw)};
  return CellsInPolygon(grid, corners, {t.x(), t.y()});
}

// The ground the robot stands on, which its lidar never sees (min_range): the cells of the disk
// of robot_radius around the sensor (cell_shapes.h), or of the vehicle's box, at sensor z -
// sensor_height. Only with dynamics, a sensor and a sensor_height.
void AddRobotFootprint(const MapParams& params, const Pose& T, PreparedScan& scan) {
  if (!scan.has_sensor || params.dynamics != Dynamics::kOn || !(params.sensor_height > 0)) return;
  const GridGeometry grid(params.resolution, params.tile_size);
  const Eigen::Vector3d& t = T.translation;
  scan.footprint_box = params.footprint_length > 0 && params.footprint_width > 0;
  scan.footprint_cells = scan.footprint_box
                             ? FootprintBoxCells(params, grid, T)
                             : CellsInDisk(grid, {t.x(), t.y()}, params.robot_radius);
  scan.footprint_y = t.z() - params.sensor_height;
}

// One observation per cell, in the canonical (ix, iy) order that makes every later sum
// independent of how the map is cut into tiles (semantics 3).
std::vector<ObservedCell> SortAndReduce(const std::vector<BinnedPoint>& binned,
                                        const CellBox& bounds, Observation mode) {
  std::vector<uint64_t>& keys = binned_keys;
  keys.resize(binned.size());
  const uint64_t height = static_cast<uint64_t>(bounds.height());
  for (size_t i = 0; i < binned.size(); ++i) {
    keys[i] = internal::CellSortKey(int64_t{binned[i].ix} - bounds.min.x,
                                    int64_t{binned[i].iy} - bounds.min.y, height);
  }
  const std::vector<uint32_t> order = internal::RadixSortOrder(keys);
  internal::ReleaseIfLarge(keys);
  return ReduceCells(binned, order, mode);
}

}  // namespace

Result<PreparedScan> PrepareScan(const MapParams& params, std::span<const Point3f> points,
                                 const Pose& T, bool frame_is_map) {
  if (Status s = ValidatePose(T, params); !s.ok()) return s;
  PreparedScan scan;
  scan.sensor_z = T.translation.z();
  scan.has_sensor = !frame_is_map;
  scan.sensor_x = T.translation.x();
  scan.sensor_y = T.translation.y();
  CellBox bounds;
  std::vector<BinnedPoint>& binned = binned_points;
  TransformAndBin(params, points, T, frame_is_map, scan.counts, bounds, binned);
  AddRobotFootprint(params, T, scan);
  if (!binned.empty()) scan.cells = SortAndReduce(binned, bounds, params.observation);
  internal::ReleaseIfLarge(binned);
  if (!binned.empty() || !scan.footprint_cells.empty()) internal::ComputeScanTiles(params, scan);
  return scan;
}

int ScanReachCells(const MapParams& params) {
  const double reach = 2 * params.kernel_length + params.robot_radius +
                       (params.dynamics == Dynamics::kOn ? params.clear_ray_length : 0.0);
  return static_cast<int>(std::ceil(reach / params.resolution)) + 2;
}

std::shared_ptr<const std::vector<ObservedCell>> WholeCellsOf(const MapParams& params,
                                                              const PreparedScan& scan) {
  if (!KeepsTransients(params) || !scan.has_sensor) return nullptr;
  if (scan.whole_cells) return scan.whole_cells;
  return std::make_shared<const std::vector<ObservedCell>>(scan.cells);
}

PreparedScan RestrictScan(const MapParams& params, const PreparedScan& scan, const CellBox& keep,
                          std::shared_ptr<const std::vector<ObservedCell>> whole) {
  PreparedScan out;
  out.counts = scan.counts;
  out.sensor_z = scan.sensor_z;
  out.has_sensor = scan.has_sensor;
  out.sensor_x = scan.sensor_x;
  out.sensor_y = scan.sensor_y;
  for (const ObservedCell& c : scan.cells) {
    if (keep.Contains(c.cell)) out.cells.push_back(c);  // stays sorted
  }
  for (const CellIndex& c : scan.footprint_cells) {
    if (keep.Contains(c)) out.footprint_cells.push_back(c);
  }
  out.footprint_y = scan.footprint_y;
  out.footprint_box = scan.footprint_box;
  out.stamp_ns = scan.stamp_ns;
  out.whole_cells = whole ? std::move(whole) : WholeCellsOf(params, scan);
  if (!out.cells.empty() || !out.footprint_cells.empty()) internal::ComputeScanTiles(params, out);
  return out;
}

}  // namespace bgkmap
