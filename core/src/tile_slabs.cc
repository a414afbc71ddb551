#include "tile_slabs.h"

#include "scratch_buffer.h"

namespace bgkmap::internal {
namespace {

thread_local TileSlabs::Scratch* kept_slabs = nullptr;  // set by the thread's first Buffers()

}  // namespace

TileSlabs::Scratch& TileSlabs::Buffers() {
  thread_local Scratch s;
  kept_slabs = &s;
  return s;
}

// Registered here, not in Buffers(): ReleaseThreadScratch may run on a thread that never built
// slabs (kept_slabs null there).
const bool kKeptSlabs =
    RegisterKeptScratch({[] {
                           if (kept_slabs != nullptr) *kept_slabs = TileSlabs::Scratch();
                         },
                         [] {
                           if (kept_slabs == nullptr) return std::size_t{0};
                           return kept_slabs->values.size() * kept_slabs->cells * sizeof(double) +
                                  CapacityBytes(kept_slabs->block_max);
                         }});

TileSlabs::~TileSlabs() {
  const size_t keep = std::max<size_t>(1, kScratchKeepBytes / (s_.cells * sizeof(double)));
  if (s_.values.size() > keep) s_.values.resize(keep);
  ReleaseIfLarge(s_.block_max);
}

TileSlabs::Slab& TileSlabs::SlabOf(TileKey key) {
  auto it = std::lower_bound(slabs_.begin(), slabs_.end(), key,
                             [](const Slab& s, const TileKey& k) { return s.key < k; });
  if (it == slabs_.end() || it->key != key) {  // not in the scan's lists (a wider window)
    it = slabs_.insert(it, {key, -1});
  }
  return *it;
}

void TileSlabs::FillSlab(Slab& slab) {
  Scratch& s = s_;
  const size_t cells = static_cast<size_t>(T) * T;
  if (s.used == s.values.size()) s.values.push_back(std::make_unique<double[]>(cells));
  double* values = s.values[s.used].get();
  if (fill_(fill_arg_, slab.key, values)) {
    slab.index = static_cast<int32_t>(s.used++);
  } else {
    slab.index = -2;
  }
  const int64_t gx = int64_t{slab.key.x} - min_.x, gy = int64_t{slab.key.y} - min_.y;
  if (tiles_x_ == 0 || gx < 0 || gy < 0 || gx >= tiles_x_ || gy >= tiles_y_) return;
  // The block rows of the grid are whole rows of blocks across the rectangle.
  const int64_t row = int64_t{tiles_x_} * blocks_;
  for (int by = 0; by < blocks_; ++by) {
    for (int bx = 0; bx < blocks_; ++bx) {
      double m = kNone;  // NaN never compares below a ray: left out
      if (slab.index >= 0) {
        for (int y = by * kBlock; y < std::min(T, (by + 1) * kBlock); ++y) {
          for (int x = bx * kBlock; x < std::min(T, (bx + 1) * kBlock); ++x) {
            if (values[y * T + x] > m) m = values[y * T + x];
          }
        }
      }
      s.block_max[(gy * blocks_ + by) * row + gx * blocks_ + bx] = m;
    }
  }
}

const double* TileSlabs::Of(TileKey key) {
  if (have_last_ && key == last_key_) return last_;
  Slab& slab = SlabOf(key);
  if (slab.index == -1) FillSlab(slab);
  last_key_ = key;
  last_ = slab.index < 0 ? nullptr : s_.values[slab.index].get();
  have_last_ = true;
  return last_;
}

double TileSlabs::MaxIn(const CellBox& box) {
  constexpr double kUnknown = std::numeric_limits<double>::infinity();
  if (tiles_x_ == 0) return kUnknown;
  const int64_t x0 = int64_t{box.min.x} - int64_t{min_.x} * T;
  const int64_t y0 = int64_t{box.min.y} - int64_t{min_.y} * T;
  const int64_t x1 = int64_t{box.max.x} - int64_t{min_.x} * T;
  const int64_t y1 = int64_t{box.max.y} - int64_t{min_.y} * T;
  if (x0 < 0 || y0 < 0 || x1 >= int64_t{tiles_x_} * T || y1 >= int64_t{tiles_y_} * T) {
    return kUnknown;
  }
  const Scratch& s = s_;
  const int64_t row = int64_t{tiles_x_} * blocks_;
  double m = kNone;
  if (T % kBlock == 0) {  // the blocks are one grid across the tiles: no division per block
    for (int64_t by = y0 / kBlock; by <= y1 / kBlock; ++by) {
      const double* blocks = s.block_max.data() + by * row;
      for (int64_t bx = x0 / kBlock; bx <= x1 / kBlock; ++bx) {
        if (std::isnan(blocks[bx])) {
          Of({static_cast<int>(min_.x + bx / blocks_), static_cast<int>(min_.y + by / blocks_)});
        }
        m = std::max(m, blocks[bx]);
      }
    }
    return m;
  }
  // The start of the block after the one holding c (blocks do not cross tiles).
  const auto next = [&](int64_t c) {
    const int64_t t0 = c / T * T;
    return t0 + std::min<int64_t>(T, ((c - t0) / kBlock + 1) * kBlock);
  };
  for (int64_t y = y0; y <= y1; y = next(y)) {
    for (int64_t x = x0; x <= x1; x = next(x)) {
      const int64_t tx = x / T, ty = y / T;
      const int64_t b =
          (ty * blocks_ + (y - ty * T) / kBlock) * row + tx * blocks_ + (x - tx * T) / kBlock;
      if (std::isnan(s.block_max[b])) {
        Of({static_cast<int>(min_.x + tx), static_cast<int>(min_.y + ty)});
      }
      m = std::max(m, s.block_max[b]);
    }
  }
  return m;
}

}  // namespace bgkmap::internal
