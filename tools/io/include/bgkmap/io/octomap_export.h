// Terrain as an OctoMap ColorOcTree (.ot) that octovis opens: every known cell becomes a column
// of occupied voxels up to its elevation, coloured by traversability (green 0 .. red 1, grey
// where unknown).
#pragma once

#include <Eigen/Core>
#include <string>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct OctreeExportOptions {
  // Height of each column below the cell's elevation, metres (the tree's voxel edge is the
  // raster's pixel edge).
  double column_depth = 1.0;
};

struct OctreeExportResult {
  // OctoMap keys are 16-bit, so the tree spans +-3276 m at 0.1 m: the columns are written
  // relative to this origin (the raster's south-west corner, z = 0), which the caller reports.
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  size_t columns = 0;
  size_t voxels = 0;
};

// Needs the elevation layer; uses the traversability layer when present.
Result<OctreeExportResult> WriteColorOcTree(const Raster& raster, const std::string& path,
                                            const OctreeExportOptions& options = {});

}  // namespace bgkmap::io
