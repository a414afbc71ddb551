#include "bgkmap/client/region_split.h"

#include <algorithm>
#include <cstring>

namespace bgkmap {
namespace {

int64_t FloorTo(int64_t a, int64_t stride) {
  return (a >= 0 ? a / stride : -((-a + stride - 1) / stride)) * stride;
}

int64_t CeilDiv(int64_t a, int64_t b) { return (a + b - 1) / b; }

}  // namespace

CellBox RegionCells(const MetricBox& box, double resolution, int stride) {
  if (!(box.min_x < box.max_x) || !(box.min_y < box.max_y) || !(resolution > 0) || stride < 1) {
    return {};
  }
  const GridGeometry g(resolution, 64);  // the tile size plays no part in which cells
  const GridGeometry::CellRange xs = g.CellsOfInterval(box.min_x, box.max_x);
  const GridGeometry::CellRange ys = g.CellsOfInterval(box.min_y, box.max_y);
  const int64_t s = stride;
  CellBox cells;
  cells.min = {static_cast<int>(FloorTo(xs.first, s)), static_cast<int>(FloorTo(ys.first, s))};
  cells.max = {static_cast<int>(FloorTo(xs.last, s) + s - 1),
               static_cast<int>(FloorTo(ys.last, s) + s - 1)};
  return cells;
}

std::vector<MetricBox> RegionWindows(const MetricBox& box, double resolution, int stride,
                                     int64_t window) {
  const CellBox cells = RegionCells(box, resolution, stride);
  if (cells.empty() || window < 1) return {box};
  const int64_t s = stride, step = window * s;  // a window's edge in cells
  const int64_t across = (cells.width() + step - 1) / step,
                down = (cells.height() + step - 1) / step;
  if (across * down > static_cast<int64_t>(kMaxRegionWindows)) return {box};
  std::vector<MetricBox> windows;
  for (int64_t top = cells.max.y; top >= cells.min.y; top -= step) {  // north first
    const int64_t bottom = std::max<int64_t>(cells.min.y, top - step + 1);
    for (int64_t left = cells.min.x; left <= cells.max.x; left += step) {
      const int64_t right = std::min<int64_t>(cells.max.x, left + step - 1);
      windows.push_back(
          {static_cast<double>(left) * resolution, static_cast<double>(bottom) * resolution,
           static_cast<double>(right + 1) * resolution, static_cast<double>(top + 1) * resolution});
    }
  }
  return windows;
}

uint64_t RegionCellBudget(const ServerLimitsInfo& limits, int stride) {
  if (limits.max_region_read_cells == 0) return limits.max_region_cells;
  const uint64_t s = static_cast<uint64_t>(stride);
  const uint64_t read = limits.max_region_read_cells;
  return limits.max_region_cells > read / (s * s) ? read : limits.max_region_cells * s * s;
}

std::vector<MetricBox> SplitRegion(const MetricBox& box, double resolution, int stride,
                                   uint64_t max_cells) {
  const CellBox cells = RegionCells(box, resolution, stride);
  if (cells.empty()) return {box};  // the server names the problem
  const int64_t s = stride;
  const int64_t x0 = cells.min.x, y0 = cells.min.y, x1 = cells.max.x, y1 = cells.max.y;
  const int64_t width = x1 - x0 + 1, height = y1 - y0 + 1;
  const auto budget = static_cast<int64_t>(std::min<uint64_t>(max_cells, INT64_MAX / 4));
  if (width * height <= budget || budget < s * s) return {box};
  // Whole rows of blocks when a band of one block's height fits, else columns of blocks.
  const int64_t cols = width * s <= budget ? width : std::max(s, budget / s / s * s);
  const int64_t rows = std::max(s, budget / cols / s * s);
  if (CeilDiv(height, rows) * CeilDiv(width, cols) > static_cast<int64_t>(kMaxRegionPieces)) {
    return {box};
  }
  std::vector<MetricBox> pieces;
  for (int64_t top = y1; top >= y0; top -= rows) {  // north first
    const int64_t bottom = std::max(y0, top - rows + 1);
    for (int64_t left = x0; left <= x1; left += cols) {
      const int64_t right = std::min(x1, left + cols - 1);
      pieces.push_back(
          {static_cast<double>(left) * resolution, static_cast<double>(bottom) * resolution,
           static_cast<double>(right + 1) * resolution, static_cast<double>(top + 1) * resolution});
    }
  }
  return pieces;
}

Result<Raster> StitchRasters(const std::vector<Raster>& pieces) {
  if (pieces.empty()) return Status::InvalidArgument("no pieces to stitch");
  const Raster& first = pieces.front();
  CellBox box = first.box;
  for (const Raster& p : pieces) {
    if (p.stride != first.stride || p.layers != first.layers || p.resolution != first.resolution) {
      return Status::InvalidArgument("pieces of different strides, resolutions or layers");
    }
    box.min.x = std::min(box.min.x, p.box.min.x);
    box.min.y = std::min(box.min.y, p.box.min.y);
    box.max.x = std::max(box.max.x, p.box.max.x);
    box.max.y = std::max(box.max.y, p.box.max.y);
  }
  const int64_t s = first.stride;
  Raster out;
  out.box = box;
  out.stride = first.stride;
  out.resolution = first.resolution;
  out.layers = first.layers;
  out.cols = (static_cast<int64_t>(box.max.x) - box.min.x + 1) / s;
  out.rows = (static_cast<int64_t>(box.max.y) - box.min.y + 1) / s;
  out.x0 = first.x0;
  out.y1 = first.y1;
  out.data.assign(out.layers.size(), std::vector<float>());
  uint64_t covered = 0;
  for (const Raster& p : pieces) {
    // The north-west piece's corner is the region's.
    if (p.box.min.x == box.min.x && p.box.max.y == box.max.y) {
      out.x0 = p.x0;
      out.y1 = p.y1;
    }
    if ((p.box.min.x - box.min.x) % s != 0 || (box.max.y - p.box.max.y) % s != 0) {
      return Status::InvalidArgument("a piece is not aligned with the stride grid");
    }
    covered += static_cast<uint64_t>(p.rows * p.cols);
  }
  if (covered != static_cast<uint64_t>(out.rows * out.cols)) {
    return Status::InvalidArgument("the pieces do not tile the region");
  }
  for (std::vector<float>& d : out.data) d.resize(static_cast<size_t>(out.rows * out.cols));
  for (const Raster& p : pieces) {
    const int64_t col0 = (p.box.min.x - box.min.x) / s;
    const int64_t row0 = (box.max.y - p.box.max.y) / s;  // rows run north to south
    for (size_t l = 0; l < out.layers.size(); ++l) {
      for (int64_t r = 0; r < p.rows; ++r) {
        std::memcpy(out.data[l].data() + (row0 + r) * out.cols + col0,
                    p.data[l].data() + r * p.cols, static_cast<size_t>(p.cols) * sizeof(float));
      }
    }
  }
  return out;
}

}  // namespace bgkmap
