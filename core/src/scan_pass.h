// One scan's integration: the scan's window and parameters at hand, and the stages Integrate
// runs in order (docs/semantics.md 4-7, "Dynamics"). Internal to core.
#pragma once

#include <algorithm>
#include <utility>
#include <vector>

#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_features.h"
#include "tile_slabs.h"

namespace bgkmap {

// The per-scan work, with the scan's window and parameters at hand.
struct ScanIntegrator::Pass {
  const ScanIntegrator& self;
  const TileWindow& window;
  const int T;          // tile size
  const int64_t stamp;  // the scan's map time (forgetting)
  const bool forget;    // forgetting on and the scan stamped

  Tile* TileAt(CellIndex c) const { return window.at(self.geometry_.TileOf(c)); }

  // Forgetting's per-tile factors, remembered for the last tile asked (runs come tile by tile);
  // 1 without forgetting, so every sum is bitwise the one without it.
  mutable const Tile* gain_tile = nullptr;
  mutable double gain = 1.0;
  double GainOf(const Tile& tile) const {
    if (!forget) return 1.0;
    if (&tile != gain_tile) {
      gain_tile = &tile;
      gain = self.Gain(tile, stamp);
    }
    return gain;
  }
  mutable const Tile* read_tile = nullptr;
  mutable double read_factor = 1.0;
  double ReadFactorOf(const Tile& tile) const {
    if (!forget) return 1.0;
    if (&tile != read_tile) {
      read_tile = &tile;
      read_factor = self.ReadFactor(tile, stamp);
    }
    return read_factor;
  }

  // Calls row(tile, start, k_double, k_float, len) for every contiguous run of the kernel
  // stencil around `c` that lies in one tile. The same runs in the same order whatever the tile
  // size, up to splitting: each cell sees the same sequence of additions, so sums are bitwise
  // independent of the tiling.
  // With kSkipAbsent, runs in tiles the window does not hold (or that do not exist) are
  // skipped; otherwise every tile must be there. Every run's blocks are marked changed
  // (Tile::MarkChanged) before `row` sees it: the callers write the runs.
  template <bool kSkipAbsent = false, typename RowFn>
  void ForEachKernelRun(CellIndex c, RowFn&& row) const {
    const KernelStencil& k = self.kernel_;
    const int R = k.radius();
    const int lx = FloorMod(c.x, T), ly = FloorMod(c.y, T);
    if (lx >= R && lx + R < T && ly >= R && ly + R < T) {  // fast path: one tile
      Tile* tile = TileAt(c);
      if (kSkipAbsent && tile == nullptr) return;
      tile->MarkChanged(lx - R, ly - R, lx + R, ly + R);  // the runs' bounding square
      for (int r = 0; r < k.row_count(); ++r) {
        const int hw = k.half_width(r);
        const int start = (ly + r - R) * T + lx - hw;
        row(*tile, start, k.row_weights_double(r), k.row_weights(r), 2 * hw + 1);
      }
      return;
    }
    for (int r = 0; r < k.row_count(); ++r) {
      const int hw = k.half_width(r);
      const int gy = c.y + r - R;
      const int row_y = FloorMod(gy, T);
      int x = c.x - hw;
      const int x_end = c.x + hw;
      while (x <= x_end) {
        const TileKey key{FloorDiv(x, T), FloorDiv(gy, T)};
        const int seg_end = std::min(x_end, key.x * T + T - 1);
        Tile* tile = window.at(key);
        const int off = x - (c.x - hw);
        if (!kSkipAbsent || tile != nullptr) {
          tile->MarkChanged(x - key.x * T, row_y, seg_end - key.x * T, row_y);
          row(*tile, row_y * T + (x - key.x * T), k.row_weights_double(r) + off,
              k.row_weights(r) + off, seg_end - x + 1);
        }
        x = seg_end + 1;
      }
    }
  }

  // The stages, in the order Integrate runs them.

  // What the free-space evidence leaves for the later stages.
  struct FreeSpace {
    std::vector<TileKey> cleared;    // the clear tiles it changed (sorted)
    std::vector<CellIndex> relearn;  // cells to re-learn from the ground left, each once
  };
  // 0. Free-space evidence (dynamics, a sensor): contradicted cells keep clear_decay of their
  // statistics per contradiction, and the Beta counts within l of them are re-learnt; counts the
  // contradicted cells in `report`.
  // 0a. Transient objects (transient_confirm_s > 0, stamped scans): ground kept aside in the
  // tiles the scan writes is dropped where its appearance is confirmed and restored where it
  // expired unconfirmed (transient_ground.cc).
  void ResolveTransients(const PreparedScan& scan) const;
  FreeSpace ApplyFreeSpace(const PreparedScan& scan, ScanReport& report) const;
  // 1. Elevation (semantics 4): kernel sums, the plane moments too for bgk-ll, or the raw
  // running mean for baseline and one-step.
  void AddElevation(const PreparedScan& scan) const;
  // The heights v is computed from at the cells of tile `key` (their elevations, or bgk-ll's own
  // observations' means; NaN where none), false for a tile the window does not hold: the fill
  // of the `heights` slabs below.
  bool FillFeatureHeights(TileKey key, double* z) const;
  // 2. Traversability training values (semantics 6): v at each cell it is computed at.
  // `heights` holds FillFeatureHeights (the elevations are final once AddElevation is done).
  std::vector<std::pair<CellIndex, float>> TrainingValues(const PreparedScan& scan,
                                                          internal::TileSlabs& heights) const;
  // 3. Traversability (semantics 7): Beta pseudo-counts spread by the kernel, or the latest direct
  // value for baseline and bgk-trav.
  void AddTraversability(const std::vector<std::pair<CellIndex, float>>& values) const;
  // 3b. Ground left by a forgotten object (dynamics): the cells of `relearn` that step 3 left
  // without counts learn v from the surface around them, at the cell only, unless it is 1.
  void RelearnGroundLeft(const std::vector<CellIndex>& relearn, internal::TileSlabs& heights) const;
  // 4. The robot's footprint (dynamics, sensor_height > 0): ground and traversable evidence at
  // each cell under the robot, at the cell only.
  void AddFootprint(const PreparedScan& scan) const;

 private:
  std::vector<std::pair<CellIndex, int>> CountContradictions(const PreparedScan& scan,
                                                             std::vector<ObservedCell>& appeared,
                                                             std::vector<CellIndex>& risen) const;
  // Transient objects: the traversable cells within robot_radius + l of each appeared cell that
  // starts or continues one are kept aside.
  void KeepGroundUnder(const PreparedScan& scan, const std::vector<ObservedCell>& appeared) const;
  std::vector<CellIndex> TransientSeeds(const std::vector<ObservedCell>& appeared) const;
  void FillObservedAround(const PreparedScan& scan, TileKey key,
                          std::vector<double>& heights) const;
  bool Hidden(const PreparedScan& scan, CellIndex e, double g) const;
  void ResetBetaNear(const std::vector<std::pair<CellIndex, int>>& contradicted,
                     std::vector<const Tile*>& touched) const;
  void ResetBetaBesideRisen(const std::vector<CellIndex>& risen,
                            std::vector<const Tile*>& touched) const;
  void CutContradicted(const std::vector<std::pair<CellIndex, int>>& contradicted,
                       std::vector<const Tile*>& touched, std::vector<CellIndex>& forgotten) const;
  std::vector<CellIndex> GroundLeftBy(const std::vector<CellIndex>& forgotten,
                                      std::vector<const Tile*>& touched) const;
  template <bool kSecondMoment>
  void AddPlaneElevation(const PreparedScan& scan) const;
  template <bool kSecondMoment, bool kGain>
  void AddKernelElevation(const PreparedScan& scan) const;
  void AddRawElevation(const PreparedScan& scan) const;
  std::vector<CellIndex> KernelReachKnownCells(const PreparedScan& scan) const;
  template <bool kGain>
  void SpreadValue(CellIndex cell, float v) const;

  // Reads of the map as the scan finds it.
  bool SeenTop(const Tile& tile, int i, double f, double* top) const;
  double ClearMarginOf(const Tile& tile, int i, double f, double disagreement) const;
  void FillClearHeights(const Tile& tile, double* heights) const;
  double Elevation(CellIndex c) const;
  std::vector<CellIndex> Contradicted(const PreparedScan& scan, std::vector<ObservedCell>& appeared,
                                      std::vector<CellIndex>& risen) const;
  void AddRayContradictions(const PreparedScan& scan, std::vector<CellIndex>& out) const;
  float ValueAt(CellIndex c, std::vector<PatchPoint>& patch, internal::TileSlabs& heights) const;
};

}  // namespace bgkmap
