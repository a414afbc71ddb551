// A value per cell of the tiles a scan reads, computed once per scan and tile instead of at every
// read: the free-space test's seen tops (a dense scan's rays cross each cell near its returns ten
// times or more, and the map they read is the map as the scan finds it), and the features'
// heights (each cell is in the patch of every observed cell within the robot radius). With each
// tile's values, the highest of every 8 x 8 block of cells, so that a ray passing above every
// block it crosses needs no walk. One scan's slabs are in use at a time per thread. Internal to
// core.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/scan.h"

namespace bgkmap::internal {

class TileSlabs {
 public:
  // An unknown cell's top: no ray height is below it, so it is never contradicted.
  static constexpr double kNone = -std::numeric_limits<double>::infinity();
  static constexpr int kBlock = 8;  // cells per block edge

  // Fill(key, values) writes the value of each of tile `key`'s cells, or returns false for a
  // tile the window does not hold. `fill` must outlive this object.
  // With `blocks`, each tile's block maxima for MaxIn.
  template <typename Fill>
  TileSlabs(const PreparedScan& scan, int tile_size, bool blocks, Fill&& fill);
  ~TileSlabs();  // keeps at most kScratchKeepBytes of the thread's buffers
  TileSlabs(const TileSlabs&) = delete;
  TileSlabs& operator=(const TileSlabs&) = delete;

  // Tile `key`'s values, filled at the first call; null for a tile the window does not hold.
  // Valid as long as this object.
  const double* Of(TileKey key);
  // The highest value (NaN left out) in the blocks that meet `box`; +inf where that is not
  // known (a box outside the scan's tiles' rectangle).
  double MaxIn(const CellBox& box);

  // The buffers a thread keeps for its slabs (tile_slabs.cc keeps and releases them).
  struct Scratch {
    std::vector<std::unique_ptr<double[]>> values;  // a tile's cells each; the first `used` in use
    size_t used = 0;
    size_t cells = 0;  // per buffer
    std::vector<double> block_max;
  };

 private:
  struct Slab {
    TileKey key;
    int32_t index;  // into Scratch::values; -1: not filled; -2: no tile
  };
  // This thread's buffers, kept from scan to scan (no allocation once they have grown), at
  // most kScratchKeepBytes of slabs once a scan is done (scratch_buffer.h).
  static Scratch& Buffers();
  Slab& SlabOf(TileKey key);
  void FillSlab(Slab& slab);

  const int T;
  Scratch& s_;               // Buffers() of the constructing thread, which alone uses this object
  const int blocks_;         // per tile edge
  std::vector<Slab> slabs_;  // sorted by key
  TileKey last_key_{0, 0};   // the last Of, answered again without a search
  const double* last_ = nullptr;
  bool have_last_ = false;
  TileKey min_{0, 0};
  int tiles_x_ = 0, tiles_y_ = 0;  // the block grid's rectangle, in tiles (0: none)
  bool (*fill_)(const void*, TileKey, double*) = nullptr;
  const void* fill_arg_ = nullptr;
};

template <typename Fill>
TileSlabs::TileSlabs(const PreparedScan& scan, int tile_size, bool blocks, Fill&& fill)
    : T(tile_size), s_(Buffers()), blocks_((tile_size + kBlock - 1) / kBlock) {
  fill_arg_ = &fill;
  fill_ = [](const void* f, TileKey key, double* values) {
    return (*static_cast<const std::remove_reference_t<Fill>*>(f))(key, values);
  };
  for (const auto* list : {&scan.write_tiles, &scan.read_tiles, &scan.clear_tiles}) {
    for (const TileKey& k : *list) slabs_.push_back({k, -1});
  }
  std::sort(slabs_.begin(), slabs_.end(),
            [](const Slab& a, const Slab& b) { return a.key < b.key; });
  Scratch& s = s_;
  s.used = 0;
  if (s.cells != static_cast<size_t>(T) * T) {  // another map's tile size
    s.values.clear();
    s.cells = static_cast<size_t>(T) * T;
  }
  s.block_max.clear();
  if (slabs_.empty() || !blocks) return;
  TileKey max = slabs_.front().key;
  min_ = max;
  for (const Slab& sl : slabs_) {
    min_ = {std::min(min_.x, sl.key.x), std::min(min_.y, sl.key.y)};
    max = {std::max(max.x, sl.key.x), std::max(max.y, sl.key.y)};
  }
  const int64_t w = int64_t{max.x} - min_.x + 1, h = int64_t{max.y} - min_.y + 1;
  if (w * h > 4 * static_cast<int64_t>(slabs_.size()) + 4096) return;  // scattered: no grid
  tiles_x_ = static_cast<int>(w);
  tiles_y_ = static_cast<int>(h);
  s.block_max.assign(static_cast<size_t>(w * h) * blocks_ * blocks_,
                     std::numeric_limits<double>::quiet_NaN());  // NaN: tile not filled yet
}

}  // namespace bgkmap::internal
