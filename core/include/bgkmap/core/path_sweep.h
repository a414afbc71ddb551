// A path is its poses and the straight segments between them (docs/semantics.md, "Path checks").
// The footprint is placed at every pose and at samples along each segment, so close together
// that no point of the footprint moves more than one cell between two placements; each placement
// is judged as a pose is (path_check.h). Pure: the caller reads the swept cells' estimates.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/path_check.h"

namespace bgkmap {

// Where a placement lies: on stretch `segment`, from poses[segment] (t = 0, the pose itself)
// towards poses[segment + 1] (0 < t < 1 strictly between them). The last pose is stretch
// poses.size() - 1 at t = 0.
struct PathPlacement {
  Pose2 pose;
  uint32_t segment = 0;
  double t = 0;
};

// The placements strictly between poses a and b: n - 1 of them at t = k / n, k = 1 .. n - 1,
// with n = ceil((|b - a| + |dyaw| * reach) / resolution) (at least 1; a relative tolerance of
// 1e-9 so a distance of exactly k cells gives n = k). dyaw is b.yaw - a.yaw taken the short way
// round, in [-pi, pi]; the heading turns by t * dyaw. reach is the polygon's Reach(), 0 for a
// disk (a disk does not change as it turns). The position is a + t * (b - a).
uint64_t SegmentSteps(const Pose2& a, const Pose2& b, const Footprint& footprint,
                      double resolution);

// How many placements a path has (its poses plus the samples between them), in floating point so
// a caller can bound the work before any placement exists.
double CountPlacements(std::span<const Pose2> poses, const Footprint& footprint, double resolution);

// Every placement in path order: poses[0], the samples of segment 0, poses[1], ... The caller
// bounds CountPlacements first.
std::vector<PathPlacement> PathPlacements(std::span<const Pose2> poses, const Footprint& footprint,
                                          double resolution);

// Asked between placements, so a long check can stop (a cancelled call, a deadline): when it
// answers true, SweptCells and JudgePath return at once with a partial result to discard.
using StopRequested = std::function<bool()>;

// The swept footprint: every cell some placement's footprint covers (FootprintCells), sorted by
// (x, y), each once.
std::vector<CellIndex> SweptCells(const GridGeometry& grid, const Footprint& footprint,
                                  std::span<const PathPlacement> placements,
                                  const StopRequested& stop = {});

// A placement and the verdict on its footprint.
struct PlacementCheck {
  PathPlacement where;
  PoseCheck check;
};

// The samples strictly between two consecutive poses.
struct SegmentCheck {
  bool safe = true;                            // every sample is safe (true when there is none)
  uint32_t placement_count = 0;                // samples strictly between the poses
  std::optional<PlacementCheck> first_unsafe;  // the first unsafe sample, when one is
};

// The verdict on a path: each pose, each segment (poses.size() - 1), the first unsafe placement
// in path order and whether there is none.
struct PathVerdict {
  std::vector<PoseCheck> poses;
  std::vector<SegmentCheck> segments;
  std::optional<PlacementCheck> first_unsafe;
  bool safe = false;
};

// Judges every placement of PathPlacements(poses) on `estimates`, the estimates of `cells` =
// SweptCells(grid, footprint, placements) in that order.
PathVerdict JudgePath(const GridGeometry& grid, const Footprint& footprint,
                      std::span<const PathPlacement> placements, std::span<const CellIndex> cells,
                      std::span<const CellEstimate> estimates, const PathThresholds& thresholds,
                      const StopRequested& stop = {});

}  // namespace bgkmap
