// Integrates a prepared scan into tiles (semantics 4-7 of docs/semantics.md).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "bgkmap/core/cell_shapes.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/sparse_kernel.h"
#include "bgkmap/core/tile.h"

namespace bgkmap {

// Tile pointers for a rectangle of tile keys, resolved before integration so that integration
// never touches the map's tile table (and can run concurrently with integrations of scans whose
// tiles are disjoint). A null entry is a tile that does not exist (all cells unknown).
class TileWindow {
 public:
  // A window over `keys` (sorted, unique); every key starts as null. Dense storage over the
  // keys' bounding rectangle when that is compact, a sorted list when the keys are scattered.
  explicit TileWindow(const std::vector<TileKey>& keys = {});

  Tile* at(TileKey k) const {
    if (k.x < min_.x || k.x > max_.x || k.y < min_.y || k.y > max_.y) return nullptr;
    if (!dense_.empty()) {
      return dense_[static_cast<size_t>(k.y - min_.y) * width_ + (k.x - min_.x)];
    }
    return SparseAt(k);
  }
  void set(TileKey k, Tile* t);

 private:
  Tile* SparseAt(TileKey k) const;
  TileKey min_{0, 0}, max_{-1, -1};
  size_t width_ = 0;
  std::vector<Tile*> dense_;
  std::vector<std::pair<TileKey, Tile*>> sparse_;
};

// Wall-clock time of the paper's three stages for one scan, in seconds.
struct StageTimes {
  double elevation = 0;       // BGK elevation inference (or raw elevation update)
  double features = 0;        // traversability computation (step, slope, roughness)
  double traversability = 0;  // BGK traversability inference (or storing direct values)
};

struct ScanReport {
  ScanPointCounts counts;
  uint64_t observed_cells = 0;
  uint64_t feature_cells = 0;          // cells where v was computed
  uint64_t contradicted_cells = 0;     // cells whose confidence free-space evidence cut
  std::vector<TileKey> changed_tiles;  // sorted
  // changed_blocks[i]: the blocks of changed_tiles[i] the scan may have changed (tile_blocks.h;
  // over-approximate: no cell outside them changed).
  std::vector<TileBlocks> changed_blocks;
  StageTimes times;
};

// Stateless apart from the precomputed stencils: one instance can serve many threads.
class ScanIntegrator {
 public:
  explicit ScanIntegrator(const MapParams& params);

  // Applies `scan` to the tiles of `window`, which must hold every tile of scan.write_tiles
  // (created) and of scan.clear_tiles and scan.read_tiles (or null where absent). Stamps
  // changed tiles with `version`.
  ScanReport Integrate(const PreparedScan& scan, const TileWindow& window, uint64_t version) const;

  const KernelStencil& kernel() const { return kernel_; }

  // With dynamics on, brings every cell of `tile` within the confidence caps (scaling its
  // statistics together, which keeps its means): what a merge does after adding. No-op when off.
  void Saturate(Tile& tile) const;

  // Forgetting (dynamics on, half_life_s > 0; docs/semantics.md "Forgetting").
  bool forgetting() const { return half_life_ns_ > 0; }
  // 2^(-dt / half_life): what a statistic keeps after dt ns of map time (1 when off or dt <= 0).
  double DecayFactor(int64_t dt_ns) const;
  // Brings `tile` to map time `t` (ns): a tile as of an earlier stamp keeps DecayFactor(t - its
  // stamp) of every statistic and is stamped `t`. No-op without forgetting, for t == 0
  // (unstamped) or t <= its stamp; a tile stamped 0 (never stamped) is only stamped.
  void Advance(Tile& tile, int64_t t) const;
  // The factor of a contribution made at map time `t` to `tile`: DecayFactor(stamp - t) for a
  // late scan (t before the tile's stamp), else 1.
  double Gain(const Tile& tile, int64_t t) const;
  // The factor that reads `tile`'s statistics as of map time `t` without changing it:
  // DecayFactor(t - stamp) for a tile behind t, else 1.
  double ReadFactor(const Tile& tile, int64_t t) const;

 private:
  struct Pass;  // one scan's stages (core/src/scan_pass.h)
  struct Caps {
    double w = 0;             // elevation weight cap (0: none)
    float ab = 0;             // Beta pseudo-count cap (0: none)
    double forget_below = 0;  // a contradicted cell left with less weight is forgotten
  };
  Caps caps_;
  // bgk-obstacle: the weight of a cell's own v, the kernel's sum over its stencil (the weight a
  // cell gets when every cell within l is observed once), float as the Beta counts.
  float direct_weight_ = 0.0f;
  double half_life_ns_ = 0;  // > 0: forgetting on
  MapParams params_;
  GridGeometry geometry_;
  KernelStencil kernel_;
  std::vector<CellIndex> neighbourhood_;  // offsets within robot_radius, inclusive
  int neighbourhood_radius_;              // largest |offset| in neighbourhood_
  // Dynamics: the offsets of neighbourhood_ outside the kernel's support (distance < l).
  std::vector<CellIndex> beside_kernel_;
  // Dynamics: offsets within robot_radius + kernel_length, the cells whose statistics a surface
  // at the centre reaches (elevation within l, traversability within r + l): what a forgotten
  // surface taught (GroundLeftBy), what an appearance hides (transient objects).
  std::vector<CellIndex> evidence_reach_;
  int evidence_reach_radius_ = 0;
  // Its half height at each dx in [-radius, radius] (the disk's column dx is dy in [-h, h]).
  std::vector<int> evidence_reach_half_;
};

}  // namespace bgkmap
