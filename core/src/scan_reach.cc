#include "scan_reach.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <iterator>
#include <limits>

#include "bgkmap/core/cell_shapes.h"
#include "bgkmap/core/grid.h"

namespace bgkmap::internal {
namespace {

// GridGeometry::TileOf with a shift where the tile size is a power of two (the default 64): a
// scan's cells each ask for several tiles, and the divisions were most of this file's time.
class TileOfCell {
 public:
  explicit TileOfCell(int tile_size)
      : T(tile_size),
        shift_(std::has_single_bit(static_cast<unsigned>(tile_size))
                   ? std::countr_zero(static_cast<unsigned>(tile_size))
                   : -1) {}
  TileKey operator()(CellIndex c) const { return {Along(c.x), Along(c.y)}; }

 private:
  int Along(int v) const { return shift_ >= 0 ? v >> shift_ : FloorDiv(v, T); }  // floor (C++20)
  const int T;
  const int shift_;
};

// A set of tiles, most of them within a box, the box's kept as one flag per tile: a scan's cells
// name the same few tiles over and over, and flagging them costs less than sorting the repeats
// away. Tiles outside the box (there is none when the box holds more than kMaxFlags tiles: a
// cloud spread over a huge area) go to a list, sorted and made unique when listed.
class TileSet {
 public:
  TileSet(TileKey lo, TileKey hi) : lo_(lo) {
    const int64_t w = int64_t{hi.x} - lo.x + 1, h = int64_t{hi.y} - lo.y + 1;
    if (w > 0 && h > 0 && w * h <= kMaxFlags) {
      width_ = w;
      height_ = h;
      flags_.assign(static_cast<size_t>(w * h), 0);
    }
  }
  void Add(TileKey t) {
    const int64_t x = int64_t{t.x} - lo_.x, y = int64_t{t.y} - lo_.y;
    if (x >= 0 && x < width_ && y >= 0 && y < height_) {
      flags_[static_cast<size_t>(x * height_ + y)] = 1;
    } else if (others_.empty() || others_.back() != t) {
      others_.push_back(t);
    }
  }
  // Every tile added, once each, in order.
  std::vector<TileKey> List() {
    std::vector<TileKey> flagged;
    for (size_t i = 0; i < flags_.size(); ++i) {
      if (flags_[i] != 0) {
        const int64_t k = static_cast<int64_t>(i);
        flagged.push_back(
            {static_cast<int>(lo_.x + k / height_), static_cast<int>(lo_.y + k % height_)});
      }
    }
    if (others_.empty()) return flagged;
    std::sort(others_.begin(), others_.end());
    std::vector<TileKey> out;
    std::set_union(flagged.begin(), flagged.end(), others_.begin(), others_.end(),
                   std::back_inserter(out));
    return out;
  }

 private:
  static constexpr int64_t kMaxFlags = int64_t{1} << 22;
  TileKey lo_;
  int64_t width_ = 0, height_ = 0;
  std::vector<uint8_t> flags_;
  std::vector<TileKey> others_;
};

// The tiles of the cells' bounding box grown by `margin` cells.
TileSet TileSetAround(const GridGeometry& geo, const std::vector<ObservedCell>& cells,
                      int64_t margin) {
  CellBox box;
  for (const ObservedCell& oc : cells) box.Extend(oc.cell);
  if (box.empty()) return TileSet({0, 0}, {-1, -1});
  auto clamp = [](int64_t v) {
    return static_cast<int>(
        std::clamp<int64_t>(v, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
  };
  return TileSet(
      geo.TileOf({clamp(int64_t{box.min.x} - margin), clamp(int64_t{box.min.y} - margin)}),
      geo.TileOf({clamp(int64_t{box.max.x} + margin), clamp(int64_t{box.max.y} + margin)}));
}

// The tiles containing at least one offset cell of `reach` around each observed cell.
// `reach(dx, dy)` must be a disk-like predicate (true at 0, monotone in |offset|) contained in
// the square of half-size `radius`, so testing the tile cell nearest to the centre suffices.
template <typename Reach>
std::vector<TileKey> CollectTiles(const GridGeometry& geo, const std::vector<ObservedCell>& cells,
                                  int radius, const Reach& reach) {
  TileSet tiles = TileSetAround(geo, cells, radius);
  const TileOfCell tile_of(geo.tile_size());
  for (const ObservedCell& oc : cells) {
    const CellIndex c = oc.cell;
    const TileKey lo = tile_of({c.x - radius, c.y - radius});
    const TileKey hi = tile_of({c.x + radius, c.y + radius});
    if (lo == hi) {
      tiles.Add(lo);
      continue;
    }
    for (int ty = lo.y; ty <= hi.y; ++ty) {
      for (int tx = lo.x; tx <= hi.x; ++tx) {
        const CellBox box = geo.TileBox({tx, ty});
        const int dx = std::clamp(c.x, box.min.x, box.max.x) - c.x;
        const int dy = std::clamp(c.y, box.min.y, box.max.y) - c.y;
        if (reach(dx, dy)) tiles.Add({tx, ty});
      }
    }
  }
  return tiles.List();
}

}  // namespace

void ComputeScanTiles(const MapParams& p, PreparedScan& scan) {
  const GridGeometry geo(p.resolution, p.tile_size);
  const int kernel_radius = static_cast<int>(std::ceil(p.kernel_length / p.resolution));
  const int robot_radius = static_cast<int>(std::ceil(p.robot_radius / p.resolution));

  // Writes: the kernel support of every observed cell (the observed cell alone for baseline).
  std::vector<TileKey> writes =
      p.method == Method::kBaseline
          ? CollectTiles(geo, scan.cells, 0, [](int, int) { return true; })
          : CollectTiles(geo, scan.cells, kernel_radius, [&](int dx, int dy) {
              return InKernelSupport(dx, dy, p.resolution, p.kernel_length);
            });

  // The robot's footprint: its cells' own tiles.
  if (!scan.footprint_cells.empty()) {
    for (const CellIndex& c : scan.footprint_cells) writes.push_back(geo.TileOf(c));
    std::sort(writes.begin(), writes.end());
    writes.erase(std::unique(writes.begin(), writes.end()), writes.end());
  }

  // Reads: the robot-radius patch of every cell whose v is computed.
  std::vector<TileKey> reads;
  if (p.method == Method::kBgkTrav) {
    const double reach = kernel_radius + robot_radius + 1.0;  // Minkowski sum, generously
    reads = CollectTiles(geo, scan.cells, kernel_radius + robot_radius + 1,
                         [&](int dx, int dy) { return std::hypot(dx, dy) <= reach; });
  } else {
    reads = CollectTiles(geo, scan.cells, robot_radius, [&](int dx, int dy) {
      return OffsetWithinRadius(dx, dy, p.robot_radius, p.resolution);
    });
  }
  // Rays: the tiles of each ray's last clear_ray_length metres (its bounding box of tiles), and
  // with the slack below also those of the cells within robot_radius of what rose (without rays
  // too: clear_ray_length 0).
  std::vector<TileKey> rays;
  if (p.dynamics == Dynamics::kOn && scan.has_sensor) {
    const double res = p.resolution;
    const double sx = scan.sensor_x / res, sy = scan.sensor_y / res;
    const double length = p.clear_ray_length / res;
    // Slack each way: the cells the segment touches, the reach of the traversability evidence
    // around them (robot_radius + l: a forgotten cell's neighbours there re-learn theirs) and
    // the robot-radius patch around those (the surface they re-learn from).
    const int slack = kernel_radius + 2 * robot_radius + 1;
    // A ray ends within `length` of its cell: the tiles lie within that and the slack.
    TileSet tiles =
        TileSetAround(geo, scan.cells, static_cast<int64_t>(std::ceil(length)) + slack + 2);
    const TileOfCell tile_of(geo.tile_size());
    for (const ObservedCell& oc : scan.cells) {
      const double ex = oc.cell.x + 0.5, ey = oc.cell.y + 0.5;
      const double dist = std::hypot(sx - ex, sy - ey);
      const double f = dist > length ? length / dist : 1.0;
      const double fx = ex + (sx - ex) * f, fy = ey + (sy - ey) * f;
      const TileKey lo = tile_of({static_cast<int>(std::floor(std::min(ex, fx))) - slack,
                                  static_cast<int>(std::floor(std::min(ey, fy))) - slack});
      const TileKey hi = tile_of({static_cast<int>(std::floor(std::max(ex, fx))) + slack,
                                  static_cast<int>(std::floor(std::max(ey, fy))) + slack});
      for (int ty = lo.y; ty <= hi.y; ++ty) {
        for (int tx = lo.x; tx <= hi.x; ++tx) tiles.Add({tx, ty});
      }
    }
    rays = tiles.List();
  }
  std::vector<TileKey> clears;
  std::set_difference(rays.begin(), rays.end(), writes.begin(), writes.end(),
                      std::back_inserter(clears));
  std::vector<TileKey> changeable;
  std::merge(writes.begin(), writes.end(), clears.begin(), clears.end(),
             std::back_inserter(changeable));
  std::vector<TileKey> read_only;
  std::set_difference(reads.begin(), reads.end(), changeable.begin(), changeable.end(),
                      std::back_inserter(read_only));
  scan.write_tiles = std::move(writes);
  scan.read_tiles = std::move(read_only);
  scan.clear_tiles = std::move(clears);
}

}  // namespace bgkmap::internal
