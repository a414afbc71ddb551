// What `bgkmap eval` scores on a drive besides its ground truth (docs/results.md, "Real
// drives"): the driven cells (final and on arrival) and why they are blocked, the traffic's trails
// and new obstacles, and their figures, watched scan by scan as the map is built.
#pragma once

#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/drive_causes.h"
#include "bgkmap/eval/drive_score.h"
#include "bgkmap/eval/traffic_score.h"
#include "eval_report.h"
#include "scan_source.h"

namespace bgkmap::cli {

// The drive's inputs, read once for every method.
struct DriveInputs {
  std::optional<eval::Footprint> footprint;
  std::vector<Pose> path;                               // the sequence's own poses
  std::vector<eval::DrivenCell> driven;                 // along them
  std::vector<std::vector<eval::DrivenCell>> arrivals;  // [k]: the driven cells scan k arrives at
  // Traffic (a traffic.json): the vehicles, the truth without them, and the cells each scan has
  // a return in with the sequence's own (true) poses.
  std::vector<eval::VehicleTrack> vehicles;
  std::optional<Raster> static_truth;
  std::vector<std::vector<CellIndex>> observed;
};

// Where and what the observer writes besides the scores.
struct DriveOutputs {
  std::string dir;
  bool figures = true;            // drive_<method>.png
  std::vector<int> figure_scans;  // drive_<method>_scanK.png
  std::string trace;              // <method>_<trace>: every driven cell after every scan (CSV)
  int trail_scans = 5, new_scans = 1;
};

// traffic.json (bgkmap simulate with moving objects) and the ground_truth_static.tif beside it;
// the refusal names the file.
Status LoadTraffic(const std::string& path, const MapParams& params, DriveInputs* in);

// Watches one method's map scan by scan (AfterScan after every scan, in order), then fills the
// method's drive and traffic scores from the final map (Finish).
class DriveObserver {
 public:
  DriveObserver(const MapParams& params, const std::string& method, const DriveInputs& in,
                const std::vector<SourceScan>& scans, const DriveOutputs& out);
  void AfterScan(size_t k, const TerrainMap& map);
  // The first error of AfterScan (a figure or the trace that could not be written), if any.
  Status Finish(const TerrainMap& map, MethodResult* m);

 private:
  std::string method_;
  const DriveInputs& in_;
  const std::vector<SourceScan>& scans_;
  const DriveOutputs& out_;
  std::optional<eval::TrafficJudge> traffic_;
  std::optional<eval::DriveCauses> causes_;
  eval::DriveScore on_arrival_;
  std::ofstream trace_;
  Status error_;
};

}  // namespace bgkmap::cli
