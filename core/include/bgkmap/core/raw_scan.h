// A scan as its robot sent it: the points in the sensor frame and the pose they were sent with.
// The map integrates the prepared scan (PrepareScan); a map that allows pose corrections keeps
// this beside it, to prepare the scan again with a corrected pose.
#pragma once

#include <vector>

#include "bgkmap/core/scan.h"

namespace bgkmap {

struct RawScan {
  Pose pose;                  // T_map_sensor the scan was sent with
  bool frame_is_map = false;  // PrepareScan's flag
  std::vector<Point3f> points;
  // > 0: the scan came compact with this step (docs/server.md "Compact scans"), so every
  // coordinate is float32(double(q) * quantum) for an integer q, and a store keeps it compactly.
  double quantum = 0.0;
};

}  // namespace bgkmap
