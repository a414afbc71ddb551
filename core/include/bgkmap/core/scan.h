// A lidar scan and its preparation: filtering, transformation to the map frame and binning into
// observed cells (semantics 1-3 of docs/semantics.md). Preparation reads no map state, so any
// number of scans can be prepared in parallel.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

struct Point3f {
  float x, y, z;
};

// Rigid transform T_map_sensor: p_map = rotation * p_sensor + translation.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  static Pose FromQuaternion(double qw, double qx, double qy, double qz, double tx, double ty,
                             double tz);
};

// Tolerance on |R^T R - I| (max element) and on |det R - 1| for a pose to count as rigid.
inline constexpr double kRotationTolerance = 1e-4;

// OK iff every entry is finite, the rotation is orthonormal with det +1 (within tolerance) and
// the translation lies inside the engine's coordinate range.
Status ValidatePose(const Pose& pose, const MapParams& params);

// What happened to a scan's points. kept + every dropped_* == input.
struct ScanPointCounts {
  uint64_t input = 0;
  uint64_t kept = 0;
  uint64_t dropped_nonfinite = 0;      // NaN or Inf coordinate
  uint64_t dropped_range = 0;          // |p| outside [min_range, max_range], or self-filtered
  uint64_t dropped_height = 0;         // q.z - t.z > max_height_above_sensor
  uint64_t dropped_out_of_bounds = 0;  // cell index beyond +-kMaxCellIndex
};

struct ObservedCell {
  CellIndex cell;
  double y;  // training elevation: max or mean q.z of the scan's points in the cell
  // max - min q.z of the scan's points in the cell in whole millimetres (rounded down, at most
  // 65535): a face within the cell (dynamics; 0 in a scan logged before spans were kept, which
  // replays without them)
  uint16_t span_mm = 0;
};

// A scan ready to integrate: its training set and the tiles integration will touch.
struct PreparedScan {
  std::vector<ObservedCell> cells;  // sorted by (x, y): a canonical order, independent of tiling
  ScanPointCounts counts;
  std::vector<TileKey> write_tiles;  // sorted; tiles whose statistics the scan changes
  std::vector<TileKey> read_tiles;   // sorted; tiles it reads but does not write
  // Sorted; tiles its free-space rays cross (dynamics), disjoint from the others: changed if they
  // exist (held for writing), never created.
  std::vector<TileKey> clear_tiles;
  double sensor_z = 0.0;  // t.z
  // Where the rays start, in the map frame: free-space evidence needs it. A cloud already in
  // the map frame (frame_is_map) has no sensor.
  bool has_sensor = false;
  double sensor_x = 0.0, sensor_y = 0.0;
  // The robot's footprint (sensor_height > 0, dynamics on, a sensor): the cells whose centres
  // lie within robot_radius of the sensor, or in the vehicle's box (footprint_length), sorted, and
  // the ground's height there (sensor z - sensor_height).
  std::vector<CellIndex> footprint_cells;
  double footprint_y = 0.0;
  // The footprint is the vehicle's box (footprint_length > 0): its cells' obstacle evidence is
  // cleared as the robot stands there.
  bool footprint_box = false;
  // Map time of the scan, ns (the sender's stamp; 0: unstamped). Only forgetting reads it
  // (half_life_s > 0, docs/semantics.md "Forgetting"); PrepareScan leaves it 0, the caller sets it.
  int64_t stamp_ns = 0;
  // A restricted scan's (RestrictScan) unrestricted observed cells, shared, with transient
  // objects on: whether a place is hidden from the sensor depends on returns far from it
  // (docs/semantics.md, "Transient objects"). Null in an unrestricted scan, whose `cells` are all.
  std::shared_ptr<const std::vector<ObservedCell>> whole_cells;
  const std::vector<ObservedCell>& WholeCells() const { return whole_cells ? *whole_cells : cells; }

  // write_tiles and clear_tiles, merged: every tile the scan may change.
  std::vector<TileKey> ChangeableTiles() const;
};

// Filters, transforms and bins one scan. `frame_is_map` marks a cloud already in the map frame
// with no sensor (an airborne LAS tile, a PCD map): the pose must be identity and no range or
// height-above-sensor filter applies. Fails (and touches nothing) on an invalid pose.
Result<PreparedScan> PrepareScan(const MapParams& params, std::span<const Point3f> points,
                                 const Pose& T_map_sensor, bool frame_is_map = false);

// The part of `scan` whose observed cells lie in `keep`, with its tile lists recomputed: what a
// map that holds only the cells near `keep` needs. A cell's statistics depend only on the
// observed cells within the kernel's, the robot radius' and the free-space rays' reach of it, so
// integrating the restricted scan changes every cell far enough inside `keep` exactly as the
// whole scan would, bit for bit (a cluster shard's halo, docs/scale-out.md). With transient
// objects the result also carries the whole scan's cells (whole_cells): `whole`, when a caller
// restricting one scan several times shares one copy, else a copy of its own.
PreparedScan RestrictScan(const MapParams& params, const PreparedScan& scan, const CellBox& keep,
                          std::shared_ptr<const std::vector<ObservedCell>> whole = nullptr);
// The whole cells a restriction of `scan` carries (null without transient objects).
std::shared_ptr<const std::vector<ObservedCell>> WholeCellsOf(const MapParams& params,
                                                              const PreparedScan& scan);

// How far, in cells, an observed cell's effects reach under `params` (the margin `keep` must
// have around the cells a restricted scan is to change exactly): an observation changes
// elevation within l; a traversability value reads elevation within the robot radius and spreads
// within l; a free-space ray changes cells up to clear_ray_length back from its return. Two cells
// of margin absorb rounding.
int ScanReachCells(const MapParams& params);

}  // namespace bgkmap
