#include "bgkmap/core/path_sweep.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace bgkmap {
namespace {

// b.yaw - a.yaw the short way round, in [-pi, pi].
double TurnBetween(const Pose2& a, const Pose2& b) {
  return std::remainder(b.yaw - a.yaw, 2 * std::numbers::pi);
}

// The distance any point of the footprint travels from a to b, at most (metres).
double Travel(const Pose2& a, const Pose2& b, const Footprint& footprint) {
  const double turn_reach = footprint.polygon.empty() ? 0.0 : footprint.Reach();
  return std::hypot(b.x - a.x, b.y - a.y) + std::abs(TurnBetween(a, b)) * turn_reach;
}

double StepsOf(double travel, double resolution) {
  return std::max(1.0, std::ceil(travel / resolution * (1.0 - 1e-9)));
}

void SortUnique(std::vector<CellIndex>* cells) {
  std::sort(cells->begin(), cells->end());
  cells->erase(std::unique(cells->begin(), cells->end()), cells->end());
}

// Every 16th placement: often enough to stop within milliseconds, rarely enough to cost nothing.
bool Asked(const StopRequested& stop, size_t i) { return stop && i % 16 == 0 && stop(); }

}  // namespace

uint64_t SegmentSteps(const Pose2& a, const Pose2& b, const Footprint& footprint,
                      double resolution) {
  return static_cast<uint64_t>(StepsOf(Travel(a, b, footprint), resolution));
}

double CountPlacements(std::span<const Pose2> poses, const Footprint& footprint,
                       double resolution) {
  double count = static_cast<double>(poses.size());
  for (size_t i = 0; i + 1 < poses.size(); ++i) {
    count += StepsOf(Travel(poses[i], poses[i + 1], footprint), resolution) - 1;
  }
  return count;
}

std::vector<PathPlacement> PathPlacements(std::span<const Pose2> poses, const Footprint& footprint,
                                          double resolution) {
  std::vector<PathPlacement> out;
  out.reserve(static_cast<size_t>(CountPlacements(poses, footprint, resolution)));
  for (size_t i = 0; i < poses.size(); ++i) {
    const auto segment = static_cast<uint32_t>(i);
    out.push_back({poses[i], segment, 0.0});
    if (i + 1 == poses.size()) break;
    const Pose2& a = poses[i];
    const Pose2& b = poses[i + 1];
    const uint64_t n = SegmentSteps(a, b, footprint, resolution);
    const double turn = TurnBetween(a, b);
    for (uint64_t k = 1; k < n; ++k) {
      const double t = static_cast<double>(k) / static_cast<double>(n);
      out.push_back({{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.yaw + t * turn}, segment, t});
    }
  }
  return out;
}

std::vector<CellIndex> SweptCells(const GridGeometry& grid, const Footprint& footprint,
                                  std::span<const PathPlacement> placements,
                                  const StopRequested& stop) {
  // Consecutive placements overlap almost entirely: deduplicate as the list grows, so it stays
  // near the swept area rather than the sum of the footprints.
  std::vector<CellIndex> out;
  size_t unique = 0;
  for (size_t i = 0; i < placements.size(); ++i) {
    if (Asked(stop, i)) return out;
    const std::vector<CellIndex> at = FootprintCells(grid, footprint, placements[i].pose);
    out.insert(out.end(), at.begin(), at.end());
    if (out.size() > std::max<size_t>(4096, 2 * unique)) {
      SortUnique(&out);
      unique = out.size();
    }
  }
  SortUnique(&out);
  return out;
}

PathVerdict JudgePath(const GridGeometry& grid, const Footprint& footprint,
                      std::span<const PathPlacement> placements, std::span<const CellIndex> cells,
                      std::span<const CellEstimate> estimates, const PathThresholds& thresholds,
                      const StopRequested& stop) {
  PathVerdict verdict;
  std::vector<CellEstimate> under;
  for (size_t i = 0; i < placements.size(); ++i) {
    if (Asked(stop, i)) return verdict;
    const PathPlacement& p = placements[i];
    under.clear();
    for (CellIndex c : FootprintCells(grid, footprint, p.pose)) {
      const auto at = std::lower_bound(cells.begin(), cells.end(), c);
      under.push_back(estimates[static_cast<size_t>(at - cells.begin())]);
    }
    const PoseCheck check = JudgeFootprint(under, thresholds);
    if (p.t == 0) {
      verdict.poses.push_back(check);
      verdict.segments.resize(p.segment);  // every segment before this pose, even one unsampled
    } else {
      verdict.segments.resize(std::max<size_t>(verdict.segments.size(), p.segment + 1));
      SegmentCheck& segment = verdict.segments[p.segment];
      ++segment.placement_count;
      if (!check.safe && segment.safe) {
        segment.safe = false;
        segment.first_unsafe = PlacementCheck{p, check};
      }
    }
    if (!check.safe && !verdict.first_unsafe) verdict.first_unsafe = PlacementCheck{p, check};
  }
  verdict.safe = !verdict.first_unsafe.has_value();
  return verdict;
}

}  // namespace bgkmap
