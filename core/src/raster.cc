#include "bgkmap/core/raster.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cell_estimate_inline.h"

namespace bgkmap {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Running aggregate of the cells behind one raster pixel.
struct PixelAggregate {
  double w = 0, s = 0, q = 0;
  float worst_trav = -1, worst_var = -1, worst_disagreement = -1;
  uint8_t block_reasons = 0;         // every reason any of its cells is blocked for
  bool known = false;                // some cell has statistics
  bool any_non_traversable = false;  // then the pixel is non-traversable
  bool any_unknown = false;          // else unknown if a cell with statistics is (seen too little)

  // A coarse pixel's elevation is the kernel mean of its cells' sums (bgk-ll too: planes about
  // different centres do not add); each cell's state is its own estimate's.
  void Add(const MapParams& p, const internal::EstimateConstants& k, double cw, double cs,
           double cq, float ca, float cb, const double* plane) {
    const CellEstimate e = internal::EstimateCellWith(p, k, cw, cs, cq, ca, cb, plane);
    if (std::isnan(e.elevation_weight)) return;  // no statistics
    known = true;
    any_unknown |= e.state == CellState::kUnknown;
    w += cw;
    s += cs;
    q += cq;
    any_non_traversable |= e.state == CellState::kNonTraversable;
    block_reasons |= e.block_reasons;
    if (!std::isnan(e.disagreement)) {
      worst_disagreement = std::max(worst_disagreement, e.disagreement);
    }
    if (std::isnan(e.traversability)) return;
    worst_trav = std::max(worst_trav, e.traversability);
    worst_var = std::max(worst_var, e.traversability_variance);
  }

  CellEstimate Estimate(const MapParams& p) const {
    CellEstimate e = EstimateCell(p, w, s, q, 0.0f, 0.0f);
    if (!known) return e;
    e.traversability = worst_trav >= 0 ? worst_trav : kNaN;
    e.traversability_variance = worst_var >= 0 ? worst_var : kNaN;
    e.state = any_non_traversable ? CellState::kNonTraversable
              : any_unknown       ? CellState::kUnknown
                                  : CellState::kTraversable;
    e.elevation_weight = static_cast<float>(w);
    e.disagreement = worst_disagreement >= 0 ? worst_disagreement : kNaN;
    e.block_reasons = block_reasons;
    return e;
  }
};

// Where each layer's pixels go: null for a layer not asked for. Writing a pixel is then a loop
// over the layer values the compiler unrolls, instead of a switch per requested layer.
struct LayerSinks {
  float* at[kLayerCount] = {};

  // Points each requested layer at its array; a layer asked for twice is filled once and
  // copied by CopyRepeats.
  explicit LayerSinks(Raster& r) {
    for (size_t li = 0; li < r.layers.size(); ++li) {
      float*& sink = at[static_cast<int>(r.layers[li])];
      if (sink == nullptr) sink = r.data[li].data();
    }
  }
  void Write(size_t pixel, const CellEstimate& e) const {
    for (int l = 0; l < kLayerCount; ++l) {
      if (at[l] != nullptr) at[l][pixel] = e.Get(static_cast<Layer>(l));
    }
  }
  static void CopyRepeats(Raster& r) {
    for (size_t li = 0; li < r.layers.size(); ++li) {
      for (size_t lj = 0; lj < li; ++lj) {
        if (r.layers[lj] == r.layers[li]) {
          r.data[li] = r.data[lj];
          break;
        }
      }
    }
  }
};

}  // namespace

const std::vector<float>* Raster::Find(Layer layer) const {
  for (size_t i = 0; i < layers.size(); ++i) {
    if (layers[i] == layer) return &data[i];
  }
  return nullptr;
}

Raster RasterGeometry(double map_resolution, const CellBox& box, const std::vector<Layer>& layers,
                      int stride) {
  stride = std::max(stride, 1);
  Raster r;
  r.box = box;
  r.stride = stride;
  r.layers = layers;
  r.resolution = map_resolution * stride;
  r.cols = (box.width() + stride - 1) / stride;
  r.rows = (box.height() + stride - 1) / stride;
  r.x0 = box.min.x * map_resolution;
  r.y1 = (static_cast<double>(box.max.y) + 1.0) * map_resolution;
  return r;
}

float UnknownValue(Layer layer) { return layer == Layer::kState ? 0.0f : kNaN; }

CellBox TilePatchCells(const GridGeometry& geometry, const CellBox& region, int stride,
                       TileKey tile) {
  const CellBox part = geometry.TileBox(tile).Intersect(region);
  if (part.empty()) return {};
  stride = std::max(stride, 1);
  // Offsets from the region's corner, which sits on a block corner.
  auto block_start = [&](int cell, int origin) {
    return origin + static_cast<int>((static_cast<int64_t>(cell) - origin) / stride * stride);
  };
  CellBox out;
  out.min = {block_start(part.min.x, region.min.x), block_start(part.min.y, region.min.y)};
  out.max = {block_start(part.max.x, region.min.x) + stride - 1,
             block_start(part.max.y, region.min.y) + stride - 1};
  return out.Intersect(region);
}

Raster ExtractRaster(const TerrainMap& map, const CellBox& box, const std::vector<Layer>& layers,
                     int stride) {
  const MapParams& p = map.params();
  const GridGeometry& geo = map.geometry();
  stride = std::max(stride, 1);
  Raster r = RasterGeometry(p.resolution, box, layers, stride);
  const size_t n = static_cast<size_t>(r.rows * r.cols);
  for (Layer l : layers) r.data.emplace_back(n, UnknownValue(l));
  if (box.empty()) return r;

  const LayerSinks sinks(r);
  const internal::EstimateConstants k = internal::EstimateConstants::Of(p);
  auto pixel_of = [&](int x, int y) {
    return static_cast<size_t>((box.max.y - y) / stride) * r.cols + (x - box.min.x) / stride;
  };

  std::vector<PixelAggregate> agg(stride > 1 ? n : 0);
  const TileKey lo = geo.TileOf(box.min), hi = geo.TileOf(box.max);
  const int T = p.tile_size;
  for (int ty = lo.y; ty <= hi.y; ++ty) {
    for (int tx = lo.x; tx <= hi.x; ++tx) {
      const Tile* tile = map.FindTile({tx, ty});
      if (tile == nullptr) continue;
      const CellBox part = geo.TileBox({tx, ty}).Intersect(box);
      const CellIndex o = geo.TileOrigin({tx, ty});
      for (int y = part.min.y; y <= part.max.y; ++y) {
        for (int x = part.min.x; x <= part.max.x; ++x) {
          const int i = (y - o.y) * T + (x - o.x);
          // Per-cell reads: a tile in either form (tile.h).
          const Tile::CellStats c = tile->CellAt(i);
          if (!(c.w > 0.0 || (c.a + c.b) > 0.0f)) continue;  // Tile::IsKnown
          double moments[Tile::kPlaneMoments];
          const double* plane = nullptr;
          if (tile->has_plane()) {
            tile->PlaneOf(i, moments);
            plane = moments;
          }
          if (stride == 1) {
            sinks.Write(pixel_of(x, y),
                        internal::EstimateCellWith(p, k, c.w, c.s, c.q, c.a, c.b, plane));
          } else {
            agg[pixel_of(x, y)].Add(p, k, c.w, c.s, c.q, c.a, c.b, plane);
          }
        }
      }
    }
  }
  for (size_t i = 0; i < agg.size(); ++i) {
    if (agg[i].known) sinks.Write(i, agg[i].Estimate(p));
  }
  LayerSinks::CopyRepeats(r);
  return r;
}

}  // namespace bgkmap
