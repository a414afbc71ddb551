// Double-precision points as read from georeferenced files, and their conversion to the
// engine's float points. LAS/PCD coordinates are often UTM (millions of metres): a float keeps
// only ~0.5 m there, so clouds stay double until an origin is subtracted.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "bgkmap/core/scan.h"

namespace bgkmap::io {

struct Point3d {
  double x, y, z;
};

// p - origin for every point, rounded to float. Pick an origin near the cloud (e.g. the
// rounded minimum corner) so the result keeps millimetre precision.
std::vector<Point3f> ToLocalFloat(std::span<const Point3d> points, const Eigen::Vector3d& origin);

}  // namespace bgkmap::io
