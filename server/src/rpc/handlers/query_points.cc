// QueryPoints: the chosen layers at a batch of points, read atomically.
#include <cmath>
#include <functional>
#include <optional>
#include <span>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

// At most this many points are answered on the thread that received the call (about a
// millisecond of reading at most); larger batches always go to the query pool.
constexpr size_t kMostPointsAnsweredAtOnce = 4096;

// A read of the cells: empty when it would have to wait (the answer is then left to the pool).
using CellRead =
    std::function<std::optional<Result<std::vector<CellEstimate>>>(std::span<const CellIndex>)>;

// The answer, or empty (nothing written to `response`) when `read` would have to wait.
std::optional<grpc::Status> QueryPoints(ServiceContext& ctx, const QueryControl& control,
                                        const v1::PointsRequest& request,
                                        v1::PointsResponse* response, const CellRead& read_cells) {
  const size_t n = static_cast<size_t>(request.points_size());
  if (n > ctx.limits.max_query_points) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "points: " + std::to_string(n) +
                            " points exceed server.max_query_points = " +
                            std::to_string(ctx.limits.max_query_points));
  }
  std::vector<Layer> layers;
  if (grpc::Status s = LayersFromProto(request.layers(), "layers", &layers); !s.ok()) return s;
  // The answer's size is known now: refuse it before building it.
  const uint64_t answer_bytes = static_cast<uint64_t>(n) * layers.size() * sizeof(float) + 4096;
  if (answer_bytes > ctx.limits.max_message_bytes) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "points: " + std::to_string(n) + " points x " +
                            std::to_string(layers.size()) + " layers take " +
                            std::to_string(answer_bytes) +
                            " bytes, over server.max_message_bytes = " +
                            std::to_string(ctx.limits.max_message_bytes));
  }
  const GridGeometry& g = ctx.map.geometry();
  std::vector<CellIndex> cells;
  cells.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const v1::Point2& p = request.points(static_cast<int>(i));
    const std::string field = "points[" + std::to_string(i) + "]";
    if (grpc::Status s = CheckCoordinate(p.x(), field + ".x", ctx.limits); !s.ok()) return s;
    if (grpc::Status s = CheckCoordinate(p.y(), field + ".y", ctx.limits); !s.ok()) return s;
    cells.push_back(g.CellAt(p.x(), p.y()));
  }
  if (grpc::Status s = control.Check(); !s.ok()) return s;
  const uint64_t version = ctx.map.applied_version();
  const std::optional<Result<std::vector<CellEstimate>>> read = read_cells(cells);
  if (!read) return std::nullopt;
  if (!read->ok()) return ToGrpcStatus(read->status());
  const std::vector<CellEstimate>& estimates = **read;
  for (Layer l : layers) response->add_layers(ToProto(l));
  auto* values = response->mutable_values();
  values->Reserve(static_cast<int>(n * layers.size()));
  for (const CellEstimate& e : estimates) {
    for (Layer l : layers) values->Add(e.Get(l));
  }
  response->set_map_version(version);
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* StartQueryPoints(ServiceContext& ctx, grpc::CallbackServerContext* call,
                                           PrincipalRef who, const v1::PointsRequest* request,
                                           v1::PointsResponse* response) {
  auto in_pool = [&ctx, request, response](const QueryControl& control) {
    return *QueryPoints(ctx, control, *request, response, [&ctx](std::span<const CellIndex> cells) {
      return std::optional(ctx.map.ReadCells(cells));
    });
  };
  auto at_once = [&ctx, request, response](const QueryControl& control) {
    if (static_cast<size_t>(request->points_size()) > kMostPointsAnsweredAtOnce) {
      return std::optional<grpc::Status>();
    }
    return QueryPoints(ctx, control, *request, response, [&ctx](std::span<const CellIndex> cells) {
      return ctx.map.TryReadCellsNow(cells);
    });
  };
  return RunUnaryQuery(ctx, call, std::move(who), RequestPhase::kPoints, in_pool, at_once);
}

}  // namespace bgkmap
