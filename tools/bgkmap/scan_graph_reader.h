// OctoMap scan graphs (.graph, as written by octomap::ScanGraph::writeBinary): every node is one
// scan in its sensor frame with the sensor pose. Parsed here rather than by ScanGraph::readBinary,
// which trusts the counts it reads (a corrupt count allocates or reads garbage) and, as Debian
// builds it, prints a line per node to stderr. tests/eval checks files written by octomap itself.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::cli {

struct GraphScan {
  std::vector<Point3f> points;  // sensor frame
  Pose pose;                    // T_map_sensor
};

// The nodes in file order (edges are checked, not returned). Errors name the file and the first
// inconsistency with octomap's layout.
Result<std::vector<GraphScan>> ReadScanGraph(const std::string& path);

}  // namespace bgkmap::cli
