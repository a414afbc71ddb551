#include "bgkmap/io/point_cloud.h"

namespace bgkmap::io {

std::vector<Point3f> ToLocalFloat(std::span<const Point3d> points, const Eigen::Vector3d& origin) {
  std::vector<Point3f> out;
  out.reserve(points.size());
  for (const Point3d& p : points) {
    out.push_back({static_cast<float>(p.x - origin.x()), static_cast<float>(p.y - origin.y()),
                   static_cast<float>(p.z - origin.z())});
  }
  return out;
}

}  // namespace bgkmap::io
