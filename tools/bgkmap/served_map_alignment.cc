#include "served_map_alignment.h"

#include <chrono>
#include <cmath>
#include <limits>

namespace bgkmap::cli {

MapHeightLookup RasterHeights(const Raster& raster) {
  const std::vector<float>* elevation = raster.Find(Layer::kElevation);
  const std::vector<float>* weight = raster.Find(Layer::kElevationWeight);
  const std::vector<float>* state = raster.Find(Layer::kState);
  const float per_cell = 1.0f / static_cast<float>(raster.stride * raster.stride);
  return [&raster, elevation, weight, state, per_cell](CellIndex c) {
    const MapHeight unknown{std::numeric_limits<float>::quiet_NaN(), 0.0f, false};
    if (elevation == nullptr || weight == nullptr || state == nullptr || !raster.box.Contains(c))
      return unknown;
    // core/raster.cc's pixel of a cell: rows north to south.
    const size_t i = static_cast<size_t>((raster.box.max.y - c.y) / raster.stride * raster.cols +
                                         (c.x - raster.box.min.x) / raster.stride);
    const float w = (*weight)[i];
    // A block is traversable only if every cell in it is (core/raster.h).
    return MapHeight{(*elevation)[i], std::isfinite(w) ? w * per_cell : 0.0f,
                     (*state)[i] == static_cast<float>(CellState::kTraversable)};
  };
}

Result<VerticalAlignment> AlignToServedMap(Client& client, const MapParams& params,
                                           std::span<const Point3f> points, const Pose& pose,
                                           const ServedAlignmentOptions& options,
                                           ServedAlignmentStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  Result<PreparedScan> prepared = PrepareScan(params, points, pose);
  if (!prepared.ok()) return prepared.status();
  const double r = options.align.radius_m;
  RegionQuery query;
  query.box = {prepared->sensor_x - r, prepared->sensor_y - r, prepared->sensor_x + r,
               prepared->sensor_y + r};
  query.layers = {Layer::kElevation, Layer::kElevationWeight, Layer::kState};
  query.stride = options.stride;
  query.compress = true;
  RpcResult<Raster> raster = client.QueryRegion(query);
  if (!raster.ok()) return Status::Unavailable("region query: " + raster.status().ToString());
  const VerticalAlignment a =
      AlignScanVertically(params, *prepared, RasterHeights(*raster), options.align);
  stats->region_bytes +=
      static_cast<uint64_t>(raster->rows * raster->cols) * query.layers.size() * sizeof(float);
  stats->seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (a.outcome == AlignmentOutcome::kAligned) {
    ++stats->aligned;
    stats->sum_abs_dz += std::abs(a.dz);
    stats->max_abs_dz = std::max(stats->max_abs_dz, std::abs(a.dz));
    if (a.Levelled()) {
      ++stats->levelled;
      stats->max_tilt_deg = std::max(stats->max_tilt_deg, a.TiltDegrees());
    }
  } else {
    ++stats->not_aligned;
  }
  return a;
}

}  // namespace bgkmap::cli
