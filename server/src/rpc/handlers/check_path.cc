// CheckPath: footprint safety along a path (after traversability_estimation's
// check_footprint_path and elevation_mapping_cupy's check_safety). The geometry and the verdict
// are core's (path_check.h); here the request is checked and bounded, all poses' cells are read
// in one atomic read, and the answer encoded.
#include <cmath>
#include <sstream>

#include "bgkmap/core/path_check.h"
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
// server spent minutes, then memory, on it).
grpc::Status CheckFootprintCost(const v1::PathCheckRequest& req, size_t poses, double reach,
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
  const double total = box * static_cast<double>(poses);
  if (!(total <= static_cast<double>(limits.max_path_check_cells))) {
    return {grpc::StatusCode::INVALID_ARGUMENT, "poses: " + std::to_string(poses) +
                                                    " poses x about " + Num(box) +
                                                    " footprint box cells = " + Num(total) +
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

// Each pose's verdict on its footprint's cells (first[i] .. first[i + 1] of `estimates`).
void JudgePoses(const std::vector<CellEstimate>& estimates, const std::vector<size_t>& first,
                const PathThresholds& thresholds, v1::PathCheckResponse* response) {
  int first_unsafe = -1;
  for (size_t i = 0; i + 1 < first.size(); ++i) {
    const std::span<const CellEstimate> cells(estimates.data() + first[i], first[i + 1] - first[i]);
    const PoseCheck check = JudgeFootprint(cells, thresholds);
    SetPoseCheck(check, response->add_poses());
    if (!check.safe && first_unsafe < 0) first_unsafe = static_cast<int>(i);
  }
  response->set_safe(first_unsafe < 0);
  response->set_first_unsafe_index(first_unsafe);
}

grpc::Status CheckPath(ServiceContext& ctx, const QueryControl& control,
                       const v1::PathCheckRequest& req, v1::PathCheckResponse* response) {
  const ServerLimits& limits = ctx.limits;
  const MapParams& params = ctx.map.params();
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
  if (grpc::Status s = CheckFootprintCost(req, n, footprint.Reach(), g.resolution(), limits);
      !s.ok()) {
    return s;
  }
  std::vector<CellIndex> cells;
  std::vector<size_t> first(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    if (grpc::Status s = control.Check(); !s.ok()) return s;
    first[i] = cells.size();
    const v1::Pose2& p = req.poses(static_cast<int>(i));
    const std::vector<CellIndex> at = FootprintCells(g, footprint, {p.x(), p.y(), p.yaw()});
    cells.insert(cells.end(), at.begin(), at.end());
    if (cells.size() > limits.max_region_cells) {
      return {grpc::StatusCode::INVALID_ARGUMENT,
              "poses: the footprints cover more than server.max_region_cells = " +
                  std::to_string(limits.max_region_cells) + " cells"};
    }
  }
  first[n] = cells.size();

  if (grpc::Status s = control.Check(); !s.ok()) return s;
  const uint64_t version = ctx.map.applied_version();
  const Result<std::vector<CellEstimate>> read = ctx.map.ReadCells(cells);
  if (!read.ok()) return ToGrpcStatus(read.status());
  JudgePoses(*read, first, thresholds, response);  // one atomic read
  response->set_map_version(version);
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* StartCheckPath(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                         PrincipalRef who, const v1::PathCheckRequest* request,
                                         v1::PathCheckResponse* response) {
  return RunUnaryQuery(ctx, call, std::move(who),
                       [&ctx, request, response](const QueryControl& control) {
                         return CheckPath(ctx, control, *request, response);
                       });
}

}  // namespace bgkmap
