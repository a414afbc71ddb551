// How a map copes with traffic (docs/results.md, "Real drives"): vehicles that drive through the
// scene leave trails (cells still non-traversable after the vehicle left) and are new obstacles
// where they arrive. Judged on the map after each scan, against the vehicles' footprints at every
// scan (`bgkmap simulate` writes them to traffic.json) and the truth of the world without them.
//
// A vehicle *occupies* at scan k the cells whose centre lies within robot_radius of its
// footprint then (the cells whose true state it decides, as eval/change_score.h). A cell is
// judged only where the world without the vehicles is traversable there (so the vehicle made the
// difference):
//  * trail: a cell occupied at scan k - 1 and not at k is *left* at k. It is judged on the map
//    after scan k + trail_scans - 1 (trail_scans scans of the world without the vehicle there)
//    if no vehicle occupies it at any scan from k to then and some scan from k to then has a
//    return in it (true poses: it was seen free). **Stale**: the map calls it non-traversable.
//  * new obstacle: a cell occupied at scan k and not at k - 1 is *entered* at k. It is judged on
//    the map after scan k + new_scans - 1 if a vehicle occupies it at every scan from k to then
//    and some of those scans has a return in it. **Missed**: the map does not call it
//    non-traversable (traversable or unknown).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap::eval {

// A vehicle's axis-aligned footprint [xmin, ymin, xmax, ymax] (metres) at each scan from
// first_scan on, one per scan while it is in the scene.
struct VehicleTrack {
  std::string name;  // for the report (traffic.json's name)
  int first_scan = 0;
  std::vector<std::array<double, 4>> boxes;
};

// One vehicle's share: the trail cells it left and the cells it entered. A cell two vehicles
// occupy at once counts for the first in traffic.json's order.
struct VehicleCounts {
  int64_t trail_judged = 0, trail_stale = 0;
  int64_t new_judged = 0, new_missed = 0;
  double stale_rate() const;  // NaN without judged cells
  double missed_rate() const;
};

struct TrafficCounts {
  int64_t trail_judged = 0, trail_stale = 0;
  int64_t new_judged = 0, new_missed = 0, new_unknown = 0;  // unknown: missed, not known
  std::vector<VehicleCounts> by_vehicle;                    // one per track, in the tracks' order
  // The stale cells' reasons (BlockReason, eval/drive_score.h; several may hold).
  int64_t stale_no_value = 0, stale_mean = 0, stale_variance = 0, stale_disagreement = 0;
  double stale_rate() const;   // trail_stale / trail_judged (NaN without judged cells)
  double missed_rate() const;  // new_missed / new_judged
};

class TrafficJudge {
 public:
  // `observed[k]`: the cells scan k has a return in (sorted), with its true pose.
  // `static_truth`: kState of the world without the vehicles (NaN = not judged).
  TrafficJudge(const MapParams& params, const std::vector<VehicleTrack>& tracks, int scans,
               const Raster& static_truth, const std::vector<std::vector<CellIndex>>& observed,
               int trail_scans = 5, int new_scans = 1);

  // Judges the cells due on the map after scan k (call after every scan, in order).
  void Score(int k, const TerrainMap& map);
  const TrafficCounts& counts() const { return counts_; }
  // Whether a vehicle occupies `cell` at scan k.
  bool Occupied(int k, CellIndex cell) const;
  // Whether `cell` is within robot_radius + kernel_length of a vehicle at scan k: the reach of
  // the traversability evidence a vehicle's cells give (v over robot_radius, spread over l).
  bool Near(int k, CellIndex cell) const;
  // Cells judged on the map after scan k (both kinds), for tests and figures.
  size_t DueAt(int k) const {
    return k >= 0 && k < static_cast<int>(due_.size()) ? due_[k].size() : 0;
  }

 private:
  struct Due {
    CellIndex cell;
    bool trail;   // else a new obstacle
    int vehicle;  // the track that left or entered it
  };
  std::vector<std::vector<Due>> due_;             // per scan
  std::vector<std::vector<CellIndex>> occupied_;  // per scan, sorted
  std::vector<std::vector<CellIndex>> near_;      // per scan, sorted
  TrafficCounts counts_;
};

// The cells whose centre lies within `radius` of the box [xmin, ymin, xmax, ymax].
std::vector<CellIndex> CellsNearBox(const GridGeometry& geometry, const std::array<double, 4>& box,
                                    double radius);

}  // namespace bgkmap::eval
