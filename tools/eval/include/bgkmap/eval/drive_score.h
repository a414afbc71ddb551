// A truth that needs no survey: the ground a robot drove over is traversable, and a map built
// from half of a drive's scans agrees with one built from the other half (docs/results.md,
// "Real drives").
//
// Driven cells. The robot's footprint (a disc, or a box with the sensor somewhere inside it)
// stands on the ground under the sensor at every pose: horizontally at the sensor's (x, y),
// turned to the sensor's heading (its x axis projected on the map's xy plane; a disc needs no
// heading). Between consecutive poses the footprint is swept: placed at positions linearly
// interpolated at most half a cell apart (heading interpolated along the shorter turn), since the
// robot passed there too. A cell is driven when its centre lies inside the footprint at some
// placement (boundary included). Its ground height is that of the placement nearest to it,
// sensor z minus sensor_height (NaN if sensor_height is 0: unknown). It is *arrived at* by the
// first scan whose footprint covers it: scan k's covers the placements after pose k - 1 up to
// pose k (scan 0's: pose 0 alone). Judged on the map just before that scan (built from the scans
// before it), it says what a planner saw of the ground the robot was about to drive on.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/terrain_features.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap::eval {

struct Footprint {
  enum class Shape { kDisc, kBox };
  Shape shape = Shape::kDisc;
  double radius = 0.0;                    // disc, metres
  double length = 0.0, width = 0.0;       // box, along the vehicle's x (forward) and y (left)
  double sensor_x = 0.0, sensor_y = 0.0;  // box: the sensor's position from the box's centre,
                                          // vehicle frame (x forward, y left)

  static Footprint Disc(double radius);
  static Footprint Box(double length, double width, double sensor_x = 0, double sensor_y = 0);
  // Whether a point at (dx, dy) from the sensor, in the vehicle frame, lies inside (inclusive).
  bool Contains(double dx, double dy) const;
  // The largest distance from the sensor to a point inside: cells farther are never driven.
  double Reach() const;
  std::string Describe() const;  // "disc r=0.8 m" / "box 4.8 x 1.8 m, sensor at (1.2, 0) m"
};

struct DrivenCell {
  CellIndex cell;
  double ground_z;     // sensor z - sensor_height at the nearest placement; NaN if unknown
  int first_scan = 0;  // the scan that arrives at it
};

// The driven cells of a path of sensor poses, sorted by (x, y), each once.
std::vector<DrivenCell> DrivenCells(const GridGeometry& geometry, std::span<const Pose> poses,
                                    const Footprint& footprint, double sensor_height);

// Why a known cell is non-traversable: core's BlockReason (cell_estimate.h), the conditions of
// the state rule it fails, under the names the drive scores use.
inline constexpr uint8_t kNoValue = kBlockedNoValue;
inline constexpr uint8_t kHighMean = kBlockedMean;
inline constexpr uint8_t kHighVariance = kBlockedVariance;
inline constexpr uint8_t kDisagreement = kBlockedDisagreement;

// The reasons a cell with these statistics is non-traversable under `params` (0: traversable or
// unknown): EstimateCell's block_reasons; `plane` is bgk-ll's plane moments (else null).
uint8_t BlockReasons(const MapParams& params, double w, double s, double q, float a, float b,
                     const double* plane = nullptr);
// The same for a cell of a map (0 if the cell is unknown).
uint8_t BlockReasonsAt(const TerrainMap& map, CellIndex cell);

// Step, slope and roughness at a cell as the integrator computes v there (its neighbours with
// weight within robot_radius, their elevations; bgk-ll: their own observations), on the map as
// it is. False with fewer than 3 neighbours.
bool SurfaceFeatures(const TerrainMap& map, CellIndex cell, TerrainFeatures* out);
struct SurfaceCheck {
  bool step = false, slope = false, roughness = false;  // above the critical value
};
bool CheckSurface(const TerrainMap& map, CellIndex cell, SurfaceCheck* out);

struct DriveScore {
  int64_t driven = 0;       // driven cells
  int64_t known = 0;        // of those, known to the map
  int64_t traversable = 0;  // known and traversable
  int64_t blocked = 0;      // known and non-traversable
  // Blocked cells by reason (a cell may count under several), and those with that reason only.
  int64_t no_value = 0, high_mean = 0, high_variance = 0, disagreement = 0;
  int64_t only_mean = 0, only_variance = 0, only_disagreement = 0;
  // Of the blocked cells with a high mean: those whose neighbourhood on the final surface
  // exceeds a criterion (step, slope, roughness: any may hold), and those where none does (the
  // evidence was learnt from an earlier surface, or spread in from neighbours).
  int64_t mean_step = 0, mean_slope = 0, mean_roughness = 0, mean_flat_now = 0;
  // Elevation minus the ground under the sensor, over known driven cells with a ground height.
  int64_t ground_cells = 0;
  double ground_bias = 0, ground_rms = 0;

  double known_share() const;        // known / driven
  double traversable_share() const;  // traversable / known
  // Pools another set of cells' score (the ground bias and RMS weighted by their cells).
  DriveScore& operator+=(const DriveScore& o);
};

DriveScore ScoreDrive(const TerrainMap& map, std::span<const DrivenCell> driven);

// Self-consistency of two maps of the same parameters (the odd and the even scans of a drive):
// over the cells both know, the elevation difference (b - a) and whether the states agree.
struct MapAgreement {
  int64_t common = 0;              // cells known in both
  int64_t only_a = 0, only_b = 0;  // known in one map only
  int64_t state_agree = 0;         // common cells with the same state
  int64_t both_traversable = 0, a_blocked_only = 0, b_blocked_only = 0;
  // Of the cells blocked in one map only: that map's reasons (BlockReason; several may hold).
  int64_t split_no_value = 0, split_high_mean = 0, split_high_variance = 0, split_disagreement = 0;
  double dz_mean = 0, dz_rms = 0;  // b - a, metres
  double dz_abs_p50 = 0, dz_abs_p95 = 0, dz_abs_max = 0;

  double agreement() const;  // state_agree / common (NaN without common cells)
};

// Over every cell known in either map, or only over `cells` when it is not empty.
MapAgreement CompareMaps(const TerrainMap& a, const TerrainMap& b,
                         std::span<const CellIndex> cells = {});

}  // namespace bgkmap::eval
