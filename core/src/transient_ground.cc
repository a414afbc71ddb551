// Transient objects (docs/semantics.md, "Transient objects"; issue 24, P4): the ground under
// something that appeared where the map saw traversable ground is kept aside, and comes back
// unless the appearance was still seen transient_confirm_s after it appeared.
#include <algorithm>
#include <cmath>
#include <limits>

#include "bgkmap/core/cell_estimate.h"
#include "ray_walk.h"
#include "scan_pass.h"
#include "tile_row_marks.h"

namespace bgkmap {
namespace {

// The rule's clock is the scans' stamps: off for unstamped scans and without free-space evidence.
bool TransientsOn(const MapParams& p, int64_t stamp, const PreparedScan& scan) {
  return KeepsTransients(p) && stamp != 0 && scan.has_sensor;
}

int64_t Nanoseconds(double seconds) { return static_cast<int64_t>(std::llround(seconds * 1e9)); }

bool IsTraversable(const MapParams& p, const Tile::CellStats& c) {
  return EstimateCell(p, c.w, c.s, c.q, c.a, c.b).state == CellState::kTraversable;
}

bool ByCell(const Tile::PendingGround& a, const Tile::PendingGround& b) {
  return a.local < b.local;
}

// A scan's observed cells are sorted by (x, y).
bool Before(const ObservedCell& o, CellIndex c) {
  return o.cell.x < c.x || (o.cell.x == c.x && o.cell.y < c.y);
}

// Adds each tile's new entries to its sorted list; a cell already pending keeps the ground it
// kept first.
void MergeIntoPending(std::vector<std::pair<Tile*, Tile::PendingGround>>& found) {
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second.local < b.second.local;
  });
  for (size_t begin = 0; begin < found.size();) {
    Tile* tile = found[begin].first;
    std::vector<Tile::PendingGround> fresh;
    for (; begin < found.size() && found[begin].first == tile; ++begin) {
      if (fresh.empty() || fresh.back().local != found[begin].second.local) {
        fresh.push_back(found[begin].second);
      }
    }
    std::vector<Tile::PendingGround>& pending = tile->pending();
    std::vector<Tile::PendingGround> merged;
    merged.reserve(pending.size() + fresh.size());
    std::set_union(pending.begin(), pending.end(), fresh.begin(), fresh.end(),
                   std::back_inserter(merged), ByCell);
    pending.swap(merged);
  }
}

}  // namespace

// This scan's observed heights over tile `key` grown by R = robot_radius + l cells on each side
// (-inf where none), row-major, (T + 2R) cells wide: what ResolveTransients reads around each
// entry.
void ScanIntegrator::Pass::FillObservedAround(const PreparedScan& scan, TileKey key,
                                              std::vector<double>& heights) const {
  const int R = self.evidence_reach_radius_;
  const int W = T + 2 * R;
  const int x0 = key.x * T - R, y0 = key.y * T - R;
  heights.assign(static_cast<size_t>(W) * W, -std::numeric_limits<double>::infinity());
  for (int ox = x0; ox < x0 + W; ++ox) {  // scan.cells is sorted by (x, y)
    auto it = std::lower_bound(scan.cells.begin(), scan.cells.end(), CellIndex{ox, y0}, Before);
    for (; it != scan.cells.end() && it->cell.x == ox && it->cell.y < y0 + W; ++it) {
      heights[static_cast<size_t>(it->cell.y - y0) * W + (ox - x0)] = it->y;
    }
  }
}

// Whether the scan cannot see the ground `g` at cell `e`: one of its observed cells (the whole
// scan's) stands above the line of sight from the sensor to (e, g) by more than clear_margin,
// farther than l from e (the appearance itself and the kernel's blend of it are not what hides
// the place).
bool ScanIntegrator::Pass::Hidden(const PreparedScan& scan, CellIndex e, double g) const {
  const MapParams& p = self.params_;
  const std::vector<ObservedCell>& cells = scan.WholeCells();
  const double res = p.resolution;
  const double sx = scan.sensor_x / res, sy = scan.sensor_y / res;  // cell units
  const double dist = std::hypot(sx - (e.x + 0.5), sy - (e.y + 0.5));
  const double skip = p.kernel_length / res;
  bool hidden = false;
  internal::WalkRayBack(e, sx, sy, dist, dist, [&](CellIndex c, double t) {
    if (hidden || t <= skip) return;
    const auto it = std::lower_bound(cells.begin(), cells.end(), c, Before);
    if (it == cells.end() || it->cell.x != c.x || it->cell.y != c.y) return;
    const double sight = g + (scan.sensor_z - g) * (t / dist);
    hidden = it->y > sight + p.clear_margin;
  });
  return hidden;
}

void ScanIntegrator::Pass::ResolveTransients(const PreparedScan& scan) const {
  const MapParams& p = self.params_;
  if (!TransientsOn(p, stamp, scan)) return;
  const int64_t confirm_ns = Nanoseconds(p.transient_confirm_s);
  const int64_t expire_ns = Nanoseconds(p.transient_expire_s);
  std::vector<double> heights;
  const int R = self.evidence_reach_radius_;
  const int W = T + 2 * R;
  // Decided on the map as the scan finds it, then applied: no restore is read by another's test.
  std::vector<std::pair<Tile*, Tile::PendingGround>> restore;
  for (const TileKey& key : scan.write_tiles) {
    Tile& tile = *window.at(key);
    std::vector<Tile::PendingGround>& pending = tile.pending();
    if (pending.empty()) continue;
    FillObservedAround(scan, key, heights);
    size_t kept = 0;
    for (Tile::PendingGround& g : pending) {
      const double ground = g.saved.s / g.saved.w;  // saved ground always has weight
      const int lx = g.local % T + R, ly = g.local / T + R;
      double near = -std::numeric_limits<double>::infinity();
      for (const CellIndex& d : self.evidence_reach_) {
        near = std::max(near, heights[static_cast<size_t>(ly + d.y) * W + lx + d.x]);
      }
      if (near > ground + p.clear_margin) {
        g.last_seen_ns = std::max(g.last_seen_ns, stamp);
      } else if (heights[static_cast<size_t>(ly) * W + lx] >
                 -std::numeric_limits<double>::infinity()) {
        continue;  // seen at the cell, and nothing stands above the ground: the map decides
      }
      if (g.last_seen_ns - g.appeared_ns >= confirm_ns) continue;  // confirmed: it stays
      if (stamp - g.last_seen_ns < expire_ns) {
        pending[kept++] = g;  // still undecided
        continue;
      }
      // Expired unconfirmed. In view (only not sampled) the map's evidence decides; hidden, the
      // ground comes back unless the map has already re-learnt it.
      const CellIndex e{key.x * T + g.local % T, key.y * T + g.local / T};
      if (Hidden(scan, e, ground) && !IsTraversable(p, tile.CellAt(g.local))) {
        restore.emplace_back(&tile, g);
      }
    }
    pending.resize(kept);
  }
  for (const auto& [tile, g] : restore) {
    const int i = g.local;
    tile->MarkCellChanged(i);
    tile->w()[i] = g.saved.w;
    tile->s()[i] = g.saved.s;
    tile->q()[i] = g.saved.q;
    tile->a()[i] = g.saved.a;
    tile->b()[i] = g.saved.b;
  }
}

// The appeared cells that start or continue a transient object: a return above the top of
// everything the cell has seen (its elevation plus its disagreement: clean ground until now), or
// at a cell already pending (the object moving on). An edge of a standing object, whose cell
// mixes it with the ground, appears again at every scan and is neither.
std::vector<CellIndex> ScanIntegrator::Pass::TransientSeeds(
    const std::vector<ObservedCell>& all_appeared) const {
  std::vector<CellIndex> appeared;
  for (const ObservedCell& oc : all_appeared) {
    const Tile& tile = *TileAt(oc.cell);
    const int i = self.geometry_.LocalIndex(oc.cell);
    const Tile::PendingGround probe{i, {}, 0, 0};
    double top = 0.0;
    if ((SeenTop(tile, i, 1.0, &top) && oc.y > top + self.params_.clear_margin) ||
        std::binary_search(tile.pending().begin(), tile.pending().end(), probe, ByCell)) {
      appeared.push_back(oc.cell);
    }
  }
  return appeared;
}

void ScanIntegrator::Pass::KeepGroundUnder(const PreparedScan& scan,
                                           const std::vector<ObservedCell>& all_appeared) const {
  const MapParams& p = self.params_;
  if (all_appeared.empty() || !TransientsOn(p, stamp, scan)) return;
  const std::vector<CellIndex> appeared = TransientSeeds(all_appeared);
  // New entries per tile, merged into the tiles' sorted lists at the end: every test reads the
  // map as the scan found it.
  std::vector<std::pair<Tile*, Tile::PendingGround>> found;
  // Neighbouring appearances share most of their reach: each cell is looked at once.
  internal::TileRowMarks reach(T, 1);
  const int R = self.evidence_reach_radius_;
  reach.MarkDisks(0, appeared, R, [&](int d) { return self.evidence_reach_half_[d + R]; });
  Tile* tile = nullptr;
  TileKey tile_key{0, 0};
  reach.ForEachInFirst([&](TileKey key, int i, CellIndex, const auto&) {
    if (tile == nullptr || !(key == tile_key)) {
      tile_key = key;
      // Only the tiles the scan writes: a cell elsewhere keeps its statistics through this scan.
      const bool writes = std::binary_search(scan.write_tiles.begin(), scan.write_tiles.end(), key);
      tile = writes ? window.at(key) : nullptr;
    }
    if (tile == nullptr) return;
    const std::vector<Tile::PendingGround>& pending = tile->pending();
    const Tile::PendingGround probe{i, {}, 0, 0};
    if (std::binary_search(pending.begin(), pending.end(), probe, ByCell)) return;
    const Tile::CellStats stats = tile->CellAt(i);
    if (!IsTraversable(p, stats)) return;
    found.push_back({tile, {i, stats, stamp, stamp}});
  });
  MergeIntoPending(found);
}

}  // namespace bgkmap
