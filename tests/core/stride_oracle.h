// A brute-force oracle for coarse (stride > 1) rasters, written from the rule in
// docs/semantics.md ("Rasters") and independent of ExtractRaster's aggregation: for each block of
// stride x stride cells, the elevation layers come from EstimateCell on the summed W, S and Q of
// the block's known cells; traversability and its variance are each the maximum over the known
// cells' own estimates (TerrainMap::Estimate, cell by cell), as is the disagreement; the state is
// traversable only if every cell with statistics is traversable, non-traversable if one is, and
// otherwise unknown (a cell seen too little, dynamics); the block reason is the union of the
// cells' reasons. A block without a known cell is unknown (NaN,
// state 0).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap::testing {

// One pixel of the oracle (row-major, rows north to south as in Raster).
inline std::vector<float> StrideOraclePixel(const TerrainMap& map, const CellBox& box, int stride,
                                            int col, int row, const std::vector<Layer>& layers) {
  const MapParams& p = map.params();
  const GridGeometry& geo = map.geometry();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  double w = 0, s = 0, q = 0;
  bool known = false, all_traversable = true, any_thin = false, any_blocked = false;
  float worst_trav = nan, worst_var = nan, worst_disagreement = nan;
  int reasons = 0;
  const int x0 = box.min.x + col * stride;
  const int ytop = box.max.y - row * stride;
  for (int y = ytop; y > ytop - stride && y >= box.min.y; --y) {
    for (int x = x0; x < x0 + stride && x <= box.max.x; ++x) {
      const CellEstimate e = map.Estimate({x, y});
      if (std::isnan(e.elevation_weight)) continue;  // no statistics
      known = true;
      any_thin |= e.state == CellState::kUnknown;
      any_blocked |= e.state == CellState::kNonTraversable;
      const Tile* t = map.FindTile(geo.TileOf({x, y}));
      const int i = geo.LocalIndex({x, y});
      w += t->w()[i];
      s += t->s()[i];
      q += t->q()[i];
      all_traversable &= e.state == CellState::kTraversable;
      reasons |= e.block_reasons;
      if (!std::isnan(e.disagreement)) {
        worst_disagreement = std::isnan(worst_disagreement)
                                 ? e.disagreement
                                 : std::max(worst_disagreement, e.disagreement);
      }
      if (std::isnan(e.traversability)) continue;
      worst_trav =
          std::isnan(worst_trav) ? e.traversability : std::max(worst_trav, e.traversability);
      worst_var = std::isnan(worst_var) ? e.traversability_variance
                                        : std::max(worst_var, e.traversability_variance);
    }
  }
  std::vector<float> out;
  for (Layer l : layers) {
    if (!known) {
      out.push_back(l == Layer::kState ? 0.0f : nan);
      continue;
    }
    const CellEstimate elev = EstimateCell(p, w, s, q, 0.0f, 0.0f);
    switch (l) {
      case Layer::kElevation:
      case Layer::kElevationVariance:
        out.push_back(elev.Get(l));
        break;
      case Layer::kElevationWeight:
        out.push_back(static_cast<float>(w));
        break;
      case Layer::kTraversability:
        out.push_back(worst_trav);
        break;
      case Layer::kTraversabilityVariance:
        out.push_back(worst_var);
        break;
      case Layer::kDisagreement:
        out.push_back(worst_disagreement);
        break;
      case Layer::kBlockReason:
        out.push_back(static_cast<float>(reasons));
        break;
      case Layer::kState: {
        // Seen-too-little cells (dynamics) are unknown on their own and make an otherwise
        // traversable block unknown; any blocked cell blocks it.
        const CellState st = all_traversable ? CellState::kTraversable
                             : any_blocked   ? CellState::kNonTraversable
                             : any_thin      ? CellState::kUnknown
                                             : CellState::kNonTraversable;
        out.push_back(static_cast<float>(st));
        break;
      }
    }
  }
  return out;
}

// The oracle raster of `box` at `stride`, same geometry as ExtractRaster's.
inline Raster StrideOracle(const TerrainMap& map, const CellBox& box,
                           const std::vector<Layer>& layers, int stride) {
  Raster r;
  r.box = box;
  r.stride = stride;
  r.layers = layers;
  r.resolution = map.params().resolution * stride;
  r.cols = (box.width() + stride - 1) / stride;
  r.rows = (box.height() + stride - 1) / stride;
  r.x0 = box.min.x * map.params().resolution;
  r.y1 = (static_cast<double>(box.max.y) + 1.0) * map.params().resolution;
  r.data.assign(layers.size(), std::vector<float>(static_cast<size_t>(r.rows) * r.cols));
  for (int row = 0; row < r.rows; ++row) {
    for (int col = 0; col < r.cols; ++col) {
      const std::vector<float> px = StrideOraclePixel(map, box, stride, col, row, layers);
      for (size_t l = 0; l < layers.size(); ++l) {
        r.data[l][static_cast<size_t>(row) * r.cols + col] = px[l];
      }
    }
  }
  return r;
}

}  // namespace bgkmap::testing
