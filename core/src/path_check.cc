#include "bgkmap/core/path_check.h"

#include <algorithm>
#include <cmath>

namespace bgkmap {

double Footprint::Reach() const {
  if (polygon.empty()) return radius;
  double reach = 0;
  for (const Point2& v : polygon) reach = std::max(reach, std::hypot(v.x, v.y));
  return reach;
}

std::vector<CellIndex> FootprintCells(const GridGeometry& grid, const Footprint& footprint,
                                      const Pose2& pose) {
  if (footprint.polygon.empty()) return CellsInDisk(grid, {pose.x, pose.y}, footprint.radius);
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  std::vector<Point2> placed;
  placed.reserve(footprint.polygon.size());
  for (const Point2& v : footprint.polygon) {
    placed.push_back({pose.x + c * v.x - s * v.y, pose.y + s * v.x + c * v.y});
  }
  return CellsInPolygon(grid, placed, {pose.x, pose.y});
}

PoseCheck JudgeFootprint(std::span<const CellEstimate> cells, const PathThresholds& t) {
  float worst = std::nanf(""), worst_var = std::nanf("");
  size_t unknown = 0;
  for (const CellEstimate& e : cells) {
    if (std::isnan(e.traversability)) {
      ++unknown;
      continue;
    }
    if (std::isnan(worst) || e.traversability > worst ||
        (e.traversability == worst && e.traversability_variance > worst_var)) {
      worst = e.traversability;
      worst_var = e.traversability_variance;
    }
  }
  PoseCheck out;
  out.worst_traversability = worst;
  out.worst_traversability_variance = worst_var;
  out.cell_count = static_cast<uint32_t>(cells.size());
  out.unknown_fraction = static_cast<float>(unknown) / static_cast<float>(cells.size());
  out.safe = worst < t.max_traversability && worst_var < t.max_traversability_variance &&
             out.unknown_fraction <= t.max_unknown_fraction;
  return out;
}

}  // namespace bgkmap
