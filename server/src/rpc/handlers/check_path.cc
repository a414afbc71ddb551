// CheckPath: footprint safety along a path (after traversability_estimation's
// check_footprint_path and elevation_mapping_cupy's check_safety): per pose the worst
// traversability under the footprint, its variance and the unknown fraction; all poses are read
// in one atomic read.
#include <cmath>
#include <sstream>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

struct Vec2 {
  double x, y;
};

bool InsidePolygon(const std::vector<Vec2>& poly, double x, double y) {
  bool inside = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Vec2 a = poly[i], b = poly[j];
    if ((a.y > y) != (b.y > y) && x < (b.x - a.x) * (y - a.y) / (b.y - a.y) + a.x) {
      inside = !inside;
    }
  }
  return inside;
}

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Largest distance from the pose to the footprint's edge, metres.
double FootprintReach(const v1::PathCheckRequest& req) {
  if (!req.has_polygon()) return req.radius();
  double reach = 0;
  for (const v1::Point2& v : req.polygon().vertices()) {
    reach = std::max(reach, std::hypot(v.x(), v.y()));
  }
  return reach;
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

// Cells whose centres lie in the footprint at `pose` (at least the cell under the pose). The
// pose and the reach have been bounded (CheckCoordinate, CheckFootprintCost), so every cell
// index fits.
grpc::Status FootprintCells(const v1::PathCheckRequest& req, const v1::Pose2& pose, double reach,
                            const GridGeometry& g, const ServerLimits& limits,
                            std::vector<CellIndex>* out) {
  const double c = std::cos(pose.yaw()), s = std::sin(pose.yaw());
  std::vector<Vec2> poly;
  if (req.has_polygon()) {
    for (const v1::Point2& v : req.polygon().vertices()) {
      poly.push_back({pose.x() + c * v.x() - s * v.y(), pose.y() + s * v.x() + c * v.y()});
    }
  }
  const CellIndex lo = g.CellAt(pose.x() - reach, pose.y() - reach);
  const CellIndex hi = g.CellAt(pose.x() + reach, pose.y() + reach);
  const uint64_t box_cells = static_cast<uint64_t>(int64_t{hi.x} - lo.x + 1) *
                             static_cast<uint64_t>(int64_t{hi.y} - lo.y + 1);
  if (box_cells > limits.max_footprint_cells) {
    return {grpc::StatusCode::INVALID_ARGUMENT, "footprint: about " + std::to_string(box_cells) +
                                                    " cells exceed server.max_footprint_cells = " +
                                                    std::to_string(limits.max_footprint_cells)};
  }
  const size_t first = out->size();
  for (int iy = lo.y; iy <= hi.y; ++iy) {
    for (int ix = lo.x; ix <= hi.x; ++ix) {
      const double x = g.CellCenterX(ix), y = g.CellCenterY(iy);
      const bool in =
          req.has_polygon()
              ? InsidePolygon(poly, x, y)
              : (x - pose.x()) * (x - pose.x()) + (y - pose.y()) * (y - pose.y()) <= reach * reach;
      if (in) out->push_back({ix, iy});
    }
  }
  if (out->size() == first) out->push_back(g.CellAt(pose.x(), pose.y()));
  return grpc::Status::OK;
}

// Each pose's worst traversability under its footprint (cells first[i] .. first[i + 1] of
// `estimates`), its variance and the unknown fraction, judged against the thresholds.
void JudgePoses(const std::vector<CellEstimate>& estimates, const std::vector<size_t>& first,
                double max_trav, double max_var, double max_unknown,
                v1::PathCheckResponse* response) {
  bool all_safe = true;
  int first_unsafe = -1;
  for (size_t i = 0; i + 1 < first.size(); ++i) {
    float worst = std::nanf(""), worst_var = std::nanf("");
    size_t unknown = 0;
    for (size_t k = first[i]; k < first[i + 1]; ++k) {
      const CellEstimate& e = estimates[k];
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
    const size_t count = first[i + 1] - first[i];
    const float unknown_fraction = static_cast<float>(unknown) / static_cast<float>(count);
    const bool safe = worst < max_trav && worst_var < max_var && unknown_fraction <= max_unknown;
    v1::PoseCheck* pc = response->add_poses();
    pc->set_worst_traversability(worst);
    pc->set_worst_traversability_variance(worst_var);
    pc->set_unknown_fraction(unknown_fraction);
    pc->set_cell_count(static_cast<uint32_t>(count));
    pc->set_safe(safe);
    if (!safe && all_safe) {
      all_safe = false;
      first_unsafe = static_cast<int>(i);
    }
  }
  response->set_safe(all_safe);
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
  const double max_trav =
      req.has_max_traversability() ? req.max_traversability() : params.trav_threshold;
  const double max_var = req.has_max_traversability_variance() ? req.max_traversability_variance()
                                                               : params.variance_threshold;
  const double max_unknown = req.has_max_unknown_fraction() ? req.max_unknown_fraction() : 0.0;

  const GridGeometry& g = ctx.map.geometry();
  const double reach = FootprintReach(req);
  if (grpc::Status s = CheckFootprintCost(req, n, reach, g.resolution(), limits); !s.ok()) {
    return s;
  }
  std::vector<CellIndex> cells;
  std::vector<size_t> first(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    if (grpc::Status s = control.Check(); !s.ok()) return s;
    first[i] = cells.size();
    if (grpc::Status s =
            FootprintCells(req, req.poses(static_cast<int>(i)), reach, g, limits, &cells);
        !s.ok()) {
      return s;
    }
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
  JudgePoses(*read, first, max_trav, max_var, max_unknown, response);  // one atomic read
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
