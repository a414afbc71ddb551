// CheckPath: footprint safety along a path, at its poses and between them (after
// traversability_estimation's check_footprint_path and elevation_mapping_cupy's check_safety).
// The placements, the swept cells and the verdict are core's (path_sweep.h); here the request is
// checked and bounded, the swept cells are read in one atomic read, and the answer encoded.
#include <cmath>
#include <sstream>

#include "bgkmap/core/path_check.h"
#include "bgkmap/core/path_sweep.h"
#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The request's footprint in core's terms (its fields already checked).
Footprint FootprintOf(const v1::PathCheckRequest& req) {
  Footprint f;
  if (!req.has_polygon()) {
    f.radius = req.radius();
    return f;
  }
  for (const v1::Point2& v : req.polygon().vertices()) f.polygon.push_back({v.x(), v.y()});
  return f;
}

// The cost of a path check, bounded before a single cell is visited. In doubles: a radius of
// 2e8 m is 2e9 cells, which int32 cell indices would wrap (the box then looked small and the
// server spent minutes, then memory, on it), and a path's placements grow with its length.
grpc::Status CheckFootprintCost(const v1::PathCheckRequest& req, double placements, double reach,
                                double resolution, const ServerLimits& limits) {
  const std::string field = req.has_polygon() ? "polygon" : "radius";
  // Cells of the footprint's bounding box around any pose (the pose need not be on a cell
  // centre, hence + 2).
  const double side = 2 * std::ceil(reach / resolution) + 2;
  const double box = side * side;
  if (!(box <= static_cast<double>(limits.max_footprint_cells))) {
    return {
        grpc::StatusCode::INVALID_ARGUMENT,
        field + ": a reach of " + Num(reach) + " m is a footprint box of about " + Num(box) +
            " cells at resolution " + Num(resolution) +
            " m, over server.max_footprint_cells = " + std::to_string(limits.max_footprint_cells)};
  }
  const double total = box * placements;
  if (!(total <= static_cast<double>(limits.max_path_check_cells))) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "poses: " + Num(placements) +
                " footprint placements (the poses and the samples between them, a cell apart) x "
                "about " +
                Num(box) + " footprint box cells = " + Num(total) +
                " cells exceed server.max_path_check_cells = " +
                std::to_string(limits.max_path_check_cells)};
  }
  return grpc::Status::OK;
}

void SetPoseCheck(const PoseCheck& check, v1::PoseCheck* out) {
  out->set_worst_traversability(check.worst_traversability);
  out->set_worst_traversability_variance(check.worst_traversability_variance);
  out->set_unknown_fraction(check.unknown_fraction);
  out->set_cell_count(check.cell_count);
  out->set_safe(check.safe);
}

void SetPathPoint(const PlacementCheck& p, v1::PathPoint* out) {
  out->set_x(p.where.pose.x);
  out->set_y(p.where.pose.y);
  out->set_yaw(p.where.pose.yaw);
  out->set_segment(p.where.segment);
  out->set_t(p.where.t);
  SetPoseCheck(p.check, out->mutable_check());
}

void SetVerdict(const PathVerdict& verdict, v1::PathCheckResponse* response) {
  for (const PoseCheck& check : verdict.poses) SetPoseCheck(check, response->add_poses());
  for (const SegmentCheck& segment : verdict.segments) {
    v1::SegmentCheck* out = response->add_segments();
    out->set_safe(segment.safe);
    out->set_placement_count(segment.placement_count);
    if (segment.first_unsafe) SetPathPoint(*segment.first_unsafe, out->mutable_first_unsafe());
  }
  response->set_safe(verdict.safe);
  response->set_first_unsafe_index(
      verdict.first_unsafe ? static_cast<int32_t>(verdict.first_unsafe->where.segment) : -1);
  if (verdict.first_unsafe) {
    SetPathPoint(*verdict.first_unsafe, response->mutable_first_unsafe_point());
  }
}

// The poses and the footprint: INVALID_ARGUMENT naming the field, before any work.
grpc::Status CheckPathRequest(const v1::PathCheckRequest& req, const ServerLimits& limits) {
  auto invalid = [](const std::string& m) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, m);
  };
  const size_t n = static_cast<size_t>(req.poses_size());
  if (n == 0) return invalid("poses: at least one pose is required");
  if (n > limits.max_path_poses) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "poses: " + std::to_string(n) +
                " poses exceed server.max_path_poses = " + std::to_string(limits.max_path_poses)};
  }
  if (req.has_polygon()) {
    const int nv = req.polygon().vertices_size();
    if (nv < 3 || nv > 64) {
      return invalid("polygon.vertices: " + std::to_string(nv) + " vertices, expected 3..64");
    }
    for (int i = 0; i < nv; ++i) {
      const v1::Point2& v = req.polygon().vertices(i);
      const std::string f = "polygon.vertices[" + std::to_string(i) + "]";
      if (grpc::Status s = CheckCoordinate(v.x(), f + ".x", limits); !s.ok()) return s;
      if (grpc::Status s = CheckCoordinate(v.y(), f + ".y", limits); !s.ok()) return s;
    }
  } else if (req.footprint_case() == v1::PathCheckRequest::kRadius) {
    if (!(req.radius() >= 0) || !std::isfinite(req.radius())) {
      return invalid("radius: must be a finite number >= 0");
    }
    if (grpc::Status s = CheckCoordinate(req.radius(), "radius", limits); !s.ok()) return s;
  } else {
    return invalid("footprint: set radius or polygon");
  }
  for (size_t i = 0; i < n; ++i) {
    const v1::Pose2& p = req.poses(static_cast<int>(i));
    const std::string f = "poses[" + std::to_string(i) + "]";
    if (grpc::Status s = CheckCoordinate(p.x(), f + ".x", limits); !s.ok()) return s;
    if (grpc::Status s = CheckCoordinate(p.y(), f + ".y", limits); !s.ok()) return s;
    if (!std::isfinite(p.yaw())) return invalid(f + ".yaw: must be finite");
  }
  return grpc::Status::OK;
}

grpc::Status CheckPath(ServiceContext& ctx, const QueryControl& control,
                       const v1::PathCheckRequest& req, v1::PathCheckResponse* response) {
  const ServerLimits& limits = ctx.limits;
  const MapParams& params = ctx.map.params();
  if (grpc::Status s = CheckPathRequest(req, limits); !s.ok()) return s;
  const size_t n = static_cast<size_t>(req.poses_size());
  PathThresholds thresholds;
  thresholds.max_traversability =
      req.has_max_traversability() ? req.max_traversability() : params.trav_threshold;
  thresholds.max_traversability_variance = req.has_max_traversability_variance()
                                               ? req.max_traversability_variance()
                                               : params.variance_threshold;
  thresholds.max_unknown_fraction =
      req.has_max_unknown_fraction() ? req.max_unknown_fraction() : 0.0;

  const GridGeometry& g = ctx.map.geometry();
  const Footprint footprint = FootprintOf(req);
  std::vector<Pose2> poses;
  poses.reserve(n);
  for (const v1::Pose2& p : req.poses()) poses.push_back({p.x(), p.y(), p.yaw()});
  const double placements = CountPlacements(poses, footprint, g.resolution());
  if (grpc::Status s =
          CheckFootprintCost(req, placements, footprint.Reach(), g.resolution(), limits);
      !s.ok()) {
    return s;
  }
  // The rule is core's (path_sweep.h): placements, the swept cells, one atomic read, the verdict.
  const std::vector<PathPlacement> along = PathPlacements(poses, footprint, g.resolution());
  if (grpc::Status s = control.Check(); !s.ok()) return s;
  const StopRequested stop = [&control] { return !control.Check().ok(); };
  const std::vector<CellIndex> cells = SweptCells(g, footprint, along, stop);
  if (grpc::Status s = control.Check(); !s.ok()) return s;  // the cells may be partial
  if (cells.size() > limits.max_region_cells) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "poses: the footprint swept along the path covers " + std::to_string(cells.size()) +
                " cells, more than server.max_region_cells = " +
                std::to_string(limits.max_region_cells)};
  }
  const uint64_t version = ctx.map.applied_version();
  const Result<std::vector<CellEstimate>> read = ctx.map.ReadCells(cells);
  if (!read.ok()) return ToGrpcStatus(read.status());
  if (grpc::Status s = control.Check(); !s.ok()) return s;
  const PathVerdict verdict = JudgePath(g, footprint, along, cells, *read, thresholds, stop);
  if (grpc::Status s = control.Check(); !s.ok()) return s;  // the verdict may be partial
  SetVerdict(verdict, response);
  response->set_map_version(version);
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* StartCheckPath(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                         PrincipalRef who, const v1::PathCheckRequest* request,
                                         v1::PathCheckResponse* response) {
  return RunUnaryQuery(ctx, call, std::move(who), RequestPhase::kCheckPath,
                       [&ctx, request, response](const QueryControl& control) {
                         return CheckPath(ctx, control, *request, response);
                       });
}

}  // namespace bgkmap
