#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_features.h"
#include "integration_kernels.h"
#include "radix_sort.h"
#include "ray_walk.h"
#include "scan_pass.h"
#include "scratch_buffer.h"
#include "tile_row_marks.h"
#include "tile_slabs.h"

namespace bgkmap {
namespace {

using internal::OwnHeight;

constexpr float kNoValue = std::numeric_limits<float>::quiet_NaN();

thread_local std::vector<uint64_t> cell_sort_keys;  // kept per thread (scratch_buffer.h)
const bool kKeptSortKeys =
    internal::RegisterKeptScratch({[] { std::vector<uint64_t>().swap(cell_sort_keys); },
                                   [] { return internal::CapacityBytes(cell_sort_keys); }});

// Sorts cells in (x, y) order, by a radix sort of their offsets in the cells' box: a scan's rays
// contradict up to ~10^5 cells, most of them many times over.
void SortCells(std::vector<CellIndex>& cells) {
  if (cells.size() < 256) {
    std::sort(cells.begin(), cells.end());
    return;
  }
  CellBox box;
  for (const CellIndex& c : cells) box.Extend(c);
  std::vector<uint64_t>& keys = cell_sort_keys;
  keys.resize(cells.size());
  const uint64_t height = static_cast<uint64_t>(box.height());
  for (size_t i = 0; i < cells.size(); ++i) {
    keys[i] = internal::CellSortKey(int64_t{cells[i].x} - box.min.x,
                                    int64_t{cells[i].y} - box.min.y, height);
  }
  const std::vector<uint32_t> order = internal::RadixSortOrder(keys);
  internal::ReleaseIfLarge(keys);
  std::vector<CellIndex> sorted(cells.size());
  for (size_t i = 0; i < order.size(); ++i) sorted[i] = cells[order[i]];
  cells.swap(sorted);
}

}  // namespace

// ---- Reads of the map as the scan finds it ----

// The top of what cell i of `tile` (read with factor f) has seen, for the free-space test:
// its height plus the deviation of the observations within l about their kernel mean. The
// height is the kernel mean, or a bgk-ll cell's own observations' mean where it has any: the
// cheap reads, as a ray crosses many cells. False for an unknown cell.
bool ScanIntegrator::Pass::SeenTop(const Tile& tile, int i, double f, double* top) const {
  const double w = f * tile.w()[i];
  if (!(w > 0.0)) return false;
  const MapParams& p = self.params_;
  const double s = f * tile.s()[i];
  double height = (p.lambda * p.prior_mean + s) / (p.lambda + w);
  if (tile.has_plane() && !std::isnan(OwnHeight(tile, i))) height = OwnHeight(tile, i);
  *top = height + std::sqrt(Disagreement(w, s, f * tile.q()[i]));
  return true;
}

// How far below its seen top a ray must pass through cell i of `tile` (read with factor f) to
// contradict it: clear_margin; nothing where the cell's Beta counts say ground (mean below
// trav_threshold) but what it saw spreads by more than step_crit (disagreement D). Such a cell
// holds the remains of something gone mixed into ground: a two-height mix whose higher part is
// a share p of its weight stands sqrt(D (1 - p) / p) above the mean, more than sqrt(D) for
// p < 1/2, so a ray below the top has gone through it (semantics "Dynamics").
double ScanIntegrator::Pass::ClearMarginOf(const Tile& tile, int i, double f,
                                           double disagreement) const {
  const MapParams& p = self.params_;
  if (!(disagreement > p.step_crit * p.step_crit) || !InfersTraversability(p.method)) {
    return p.clear_margin;
  }
  // The counts as a tile brought to the scan's time holds them (forgetting's rounding).
  const double a = static_cast<float>(static_cast<double>(tile.a()[i]) * f);
  const double b = static_cast<float>(static_cast<double>(tile.b()[i]) * f);
  if (!(a + b > 0.0)) return p.clear_margin;
  const double alpha = p.alpha0 + a;
  return alpha / (alpha + p.beta0 + b) < p.trav_threshold ? 0.0 : p.clear_margin;
}

// For every cell of `tile`, the height below which a ray passing through it contradicts it
// (SeenTop less ClearMarginOf), kNone where unknown; SeenTop's arithmetic written out for a
// tile without plane moments, in one pass over its arrays.
void ScanIntegrator::Pass::FillClearHeights(const Tile& tile, double* heights) const {
  const double f = ReadFactorOf(tile);
  const int n = tile.cell_count();
  if (tile.has_plane()) {
    for (int i = 0; i < n; ++i) {
      double top = 0.0;
      if (!SeenTop(tile, i, f, &top)) {
        heights[i] = internal::TileSlabs::kNone;
        continue;
      }
      const double d = Disagreement(f * tile.w()[i], f * tile.s()[i], f * tile.q()[i]);
      heights[i] = top - ClearMarginOf(tile, i, f, d);
    }
    return;
  }
  const MapParams& p = self.params_;
  const double* tw = tile.w().data();
  const double* ts = tile.s().data();
  const double* tq = tile.q().data();
  for (int i = 0; i < n; ++i) {
    const double w = f * tw[i];
    if (!(w > 0.0)) {
      heights[i] = internal::TileSlabs::kNone;
      continue;
    }
    const double s = f * ts[i];
    const double height = (p.lambda * p.prior_mean + s) / (p.lambda + w);
    const double mean = s / w;  // Disagreement(w, s, q)
    const double disagreement = std::max(0.0, (f * tq[i]) / w - mean * mean);
    heights[i] = height + std::sqrt(disagreement) - ClearMarginOf(tile, i, f, disagreement);
  }
}

// Elevation of a known cell, NaN otherwise.
double ScanIntegrator::Pass::Elevation(CellIndex c) const {
  const Tile* tile = TileAt(c);
  if (tile == nullptr) return std::numeric_limits<double>::quiet_NaN();
  const int i = self.geometry_.LocalIndex(c);
  const double f = ReadFactorOf(*tile);  // a tile the scan does not change, as of its stamp
  const MapParams& p = self.params_;
  if (tile->has_plane()) {  // the estimate's own elevation (EstimateCell)
    const double w = f * tile->w()[i];
    if (!(w > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    double m[Tile::kPlaneMoments];
    tile->PlaneOf(i, m);
    for (double& x : m) x *= f;
    return FitLocalPlane(p, w, f * tile->s()[i], 0.0, m).elevation;
  }
  const double w = f * tile->w()[i];
  if (!(w > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return (p.lambda * p.prior_mean + f * tile->s()[i]) / (p.lambda + w);
}

namespace {

// The cells a ray's walk from t0 to t1 can visit (ray_walk.h), with a cell to spare each side
// for rounding.
CellBox RayBox(CellIndex end, double sx, double sy, double dist, double t0, double t1) {
  const double x0 = end.x + 0.5, y0 = end.y + 0.5;
  const double ux = (sx - x0) / dist, uy = (sy - y0) / dist;
  const double xa = x0 + ux * t0, xb = x0 + ux * t1, ya = y0 + uy * t0, yb = y0 + uy * t1;
  return {{static_cast<int>(std::floor(std::min(xa, xb))) - 1,
           static_cast<int>(std::floor(std::min(ya, yb))) - 1},
          {static_cast<int>(std::floor(std::max(xa, xb))) + 1,
           static_cast<int>(std::floor(std::max(ya, yb))) + 1}};
}

}  // namespace

// The cells the scan's rays pass clearly below on their way to their returns, once per ray
// (semantics "Dynamics"), in the order the rays are walked. A ray whose lowest height over its
// walk is not below the highest clear height (FillClearHeights) of the blocks it crosses
// contradicts nothing there and is not walked: the same cells, bit for bit.
void ScanIntegrator::Pass::AddRayContradictions(const PreparedScan& scan,
                                                std::vector<CellIndex>& out) const {
  const MapParams& p = self.params_;
  const double res = p.resolution;
  const double sx = scan.sensor_x / res, sy = scan.sensor_y / res;
  const double length = p.clear_ray_length / res;
  // Cells within l of the return are skipped: there the kernel blends the return's own
  // surface into its neighbours, and a ray that hit a face would "contradict" the blend.
  const double skip = p.kernel_length / res;
  // Below the top of what a cell has seen: its elevation plus its disagreement's deviation, so
  // an old object's remains, mixed with new ground, still stand above a grazing ray.
  const auto fill = [&](TileKey key, double* heights) {
    const Tile* tile = window.at(key);
    if (tile == nullptr) return false;
    FillClearHeights(*tile, heights);
    return true;
  };
  internal::TileSlabs clear(scan, T, true, fill);
  internal::TileCursor at(T);
  TileKey last_key{0, 0};
  const double* tile_clear = nullptr;
  bool have_last = false;
  for (const ObservedCell& oc : scan.cells) {
    const double dist = std::hypot(sx - (oc.cell.x + 0.5), sy - (oc.cell.y + 0.5));
    if (!(dist > skip)) continue;
    const double rise = (scan.sensor_z - oc.y) / dist;  // ray height gained per cell
    const double limit = std::min(length, dist);        // the walk's t stays below it
    if (!(skip < limit)) continue;
    const double low = std::min(oc.y + rise * skip, oc.y + rise * limit);
    if (!(low < clear.MaxIn(RayBox(oc.cell, sx, sy, dist, skip, limit)))) continue;
    at.Reset(oc.cell);
    internal::WalkRayBack(oc.cell, sx, sy, length, dist, [&](CellIndex c, double t) {
      at.MoveTo(c);
      if (t < skip) return;
      if (!have_last || at.key != last_key) {  // the footprint holds every tile a ray crosses
        last_key = at.key;
        tile_clear = clear.Of(at.key);
        have_last = true;
      }
      if (tile_clear != nullptr && oc.y + rise * t < tile_clear[at.index()]) {
        out.push_back(c);
      }
    });
  }
}

// The cells this scan contradicts, sorted, each once per piece of evidence (semantics
// "Dynamics"), read from the map before the scan changes it: a return clearly above a cell's
// elevation (something appeared), and a ray passing clearly below one on its way to its return
// (what was there has gone). The first kind also in `appeared` with transient objects on, and
// where the cell had an elevation (something rose) in `risen`, both in scan order (sorted).
std::vector<CellIndex> ScanIntegrator::Pass::Contradicted(const PreparedScan& scan,
                                                          std::vector<ObservedCell>& appeared,
                                                          std::vector<CellIndex>& risen) const {
  std::vector<CellIndex> out;
  const double margin = self.params_.clear_margin;
  const bool transients = KeepsTransients(self.params_);
  for (const ObservedCell& oc : scan.cells) {
    const double m = Elevation(oc.cell);
    if (!(oc.y > m + margin)) continue;  // true for NaN (unknown)
    out.push_back(oc.cell);
    if (transients) appeared.push_back(oc);
    if (!std::isnan(m)) risen.push_back(oc.cell);
  }
  if (self.params_.clear_ray_length > 0) AddRayContradictions(scan, out);
  SortCells(out);
  return out;
}

// The heights v is computed from at the cells of tile `key`: their elevations, or for bgk-ll
// their own observations' means (NaN where there are none). False for a tile the window does
// not hold.
bool ScanIntegrator::Pass::FillFeatureHeights(TileKey key, double* z) const {
  const Tile* tile = window.at(key);
  if (tile == nullptr) return false;
  const int n = tile->cell_count();
  if (tile->has_plane()) {
    for (int i = 0; i < n; ++i) z[i] = OwnHeight(*tile, i);
    return true;
  }
  const double f = ReadFactorOf(*tile);  // 1 for the tiles the scan writes (brought to its time)
  const MapParams& p = self.params_;
  for (int i = 0; i < n; ++i) {  // Elevation's arithmetic
    const double w = f * tile->w()[i];
    z[i] = w > 0.0 ? (p.lambda * p.prior_mean + f * tile->s()[i]) / (p.lambda + w) : kNoValue;
  }
  return true;
}

// Traversability training value v at `c` from the current elevations (semantics 6), or NaN
// with fewer than three known cells within the robot radius. `heights` holds FillFeatureHeights.
float ScanIntegrator::Pass::ValueAt(CellIndex c, std::vector<PatchPoint>& patch,
                                    internal::TileSlabs& heights) const {
  patch.clear();
  const MapParams& p = self.params_;
  const double res = p.resolution;
  const int R = self.neighbourhood_radius_;
  const int lx = FloorMod(c.x, T), ly = FloorMod(c.y, T);
  if (lx >= R && lx + R < T && ly >= R && ly + R < T) {  // fast path: one tile
    const TileKey key = self.geometry_.TileOf(c);
    const double* w = window.at(key)->w().data();
    const double* z = heights.Of(key);
    const int centre = ly * T + lx;
    for (const CellIndex& o : self.neighbourhood_) {
      const int i = centre + o.y * T + o.x;
      if (!(w[i] > 0.0)) continue;
      // bgk-ll: v from the data, the cells' own observations, not from the fitted surface
      // (which fills unobserved cells, e.g. behind an occluding edge, with planes that would
      // read as steps).
      if (!std::isnan(z[i])) patch.push_back({o.x * res, o.y * res, z[i]});
    }
  } else {
    TileKey last{0, 0};
    const double* z = nullptr;
    bool have = false;
    for (const CellIndex& o : self.neighbourhood_) {
      const CellIndex n{c.x + o.x, c.y + o.y};
      const TileKey key = self.geometry_.TileOf(n);
      if (!have || key != last) {
        last = key;
        z = heights.Of(key);
        have = true;
      }
      const double h = z != nullptr ? z[self.geometry_.LocalIndex(n)] : kNoValue;
      if (!std::isnan(h)) patch.push_back({o.x * res, o.y * res, h});
    }
  }
  if (patch.size() < 3) return kNoValue;
  // A step over its critical value alone makes v 1 (TraversabilityValue): no plane fit needed.
  double zmin = patch.front().z, zmax = patch.front().z;  // as ComputeFeatures has them
  for (const PatchPoint& q : patch) {
    zmin = std::min(zmin, q.z);
    zmax = std::max(zmax, q.z);
  }
  if (DiscountStep(zmax - zmin, p.pose_sigma_z) > p.step_crit) return 1.0f;
  return static_cast<float>(
      TraversabilityValue(DiscountPoseNoise(ComputeFeatures(patch), p.pose_sigma_z), p));
}

// ---- 0. Free-space evidence ----

std::vector<std::pair<CellIndex, int>> ScanIntegrator::Pass::CountContradictions(
    const PreparedScan& scan, std::vector<ObservedCell>& appeared,
    std::vector<CellIndex>& risen) const {
  // Each contradicted cell once, with the number of rays (and returns) that contradict it.
  std::vector<std::pair<CellIndex, int>> contradicted;
  for (const CellIndex& c : Contradicted(scan, appeared, risen)) {
    if (!contradicted.empty() && contradicted.back().first == c) {
      ++contradicted.back().second;
    } else {
      contradicted.emplace_back(c, 1);
    }
  }
  return contradicted;
}

// The traversability evidence within l of a contradicted cell was learnt from a surface that is
// not there any more: it is re-learnt from this scan on.
void ScanIntegrator::Pass::ResetBetaNear(const std::vector<std::pair<CellIndex, int>>& contradicted,
                                         std::vector<const Tile*>& touched) const {
  for (const auto& [c, count] : contradicted) {
    ForEachKernelRun<true>(c, [&](Tile& tile, int start, const double*, const float*, int len) {
      float* a = tile.a().data() + start;
      float* b = tile.b().data() + start;
      bool any = false;
      for (int j = 0; j < len; ++j) any |= (a[j] != 0.0f) | (b[j] != 0.0f);
      if (!any) return;
      if (forget) self.Advance(tile, stamp);
      std::fill_n(a, len, 0.0f);
      std::fill_n(b, len, 0.0f);
      if (touched.empty() || touched.back() != &tile) touched.push_back(&tile);
    });
  }
}

// Where something rose above the ground the map knew, every cell within robot_radius of it is
// now within a robot's reach of an obstacle (its v is 1), and the counts it learnt without the
// obstacle are reset like those within l (ResetBetaNear, which has done the offsets inside the
// kernel's support already): with l = robot_radius, the cells at exactly robot_radius.
void ScanIntegrator::Pass::ResetBetaBesideRisen(const std::vector<CellIndex>& risen,
                                                std::vector<const Tile*>& touched) const {
  for (const CellIndex& c : risen) {
    for (const CellIndex& d : self.beside_kernel_) {
      const CellIndex n{c.x + d.x, c.y + d.y};
      Tile* tile = window.at(self.geometry_.TileOf(n));
      if (tile == nullptr) continue;
      const int i = self.geometry_.LocalIndex(n);
      float& a = tile->a()[i];
      float& b = tile->b()[i];
      if (a == 0.0f && b == 0.0f) continue;
      if (forget) self.Advance(*tile, stamp);
      a = b = 0.0f;
      tile->MarkCellChanged(i);
      if (touched.empty() || touched.back() != tile) touched.push_back(tile);
    }
  }
}

void ScanIntegrator::Pass::CutContradicted(
    const std::vector<std::pair<CellIndex, int>>& contradicted, std::vector<const Tile*>& touched,
    std::vector<CellIndex>& forgotten) const {
  for (const auto& [c, count] : contradicted) {
    Tile& tile = *TileAt(c);
    if (forget) self.Advance(tile, stamp);
    const int i = self.geometry_.LocalIndex(c);
    // Independent rays are independent evidence: each keeps clear_decay of what is left.
    double keep = 1.0;
    for (int k = 0; k < count && keep > 0.0; ++k) keep *= self.params_.clear_decay;
    tile.ScaleCell(i, keep);
    tile.a()[i] = tile.b()[i] = 0.0f;  // as ResetBetaNear leaves them, so GroundLeftBy skips it
    // What is left is less than a tenth of one observation: forgotten, the cell is unknown
    // again until something is seen there (a removed object over ground no ray reaches).
    if (tile.w()[i] < self.caps_.forget_below) {
      tile.ClearCell(i);
      forgotten.push_back(c);
    }
    if (touched.empty() || touched.back() != &tile) touched.push_back(&tile);
  }
}

// The cells near a forgotten cell that still hold Beta counts (the contradicted cells' were
// zeroed by the cut): ground an object stood beside and left. Within l every one; beyond, as far
// as the object's obstacle evidence reached (robot_radius + l: its step made v over r, spread
// over l), those whose counts, as of the scan's time, say "obstacle". Each is reset here, as
// ResetBetaNear would, and so listed once. The cells are those of the union of the disks around
// the forgotten cells, each visited once (forgotten cells lie close: their disks overlap).
std::vector<CellIndex> ScanIntegrator::Pass::GroundLeftBy(const std::vector<CellIndex>& forgotten,
                                                          std::vector<const Tile*>& touched) const {
  std::vector<CellIndex> out;
  if (!InfersTraversability(self.params_.method) || forgotten.empty()) return out;
  const MapParams& p = self.params_;
  const int R = self.evidence_reach_radius_, RK = self.kernel_.radius();
  constexpr int kReach = 0, kWithinL = 1;
  internal::TileRowMarks marks(T, 2);
  // Both disks are symmetric: a row's half width is a column's half height.
  marks.MarkDisks(kReach, forgotten, R, [&](int d) { return self.evidence_reach_half_[d + R]; });
  marks.MarkDisks(kWithinL, forgotten, RK, [&](int d) { return self.kernel_.half_width(d + RK); });
  Tile* tile = nullptr;
  TileKey tile_key{0, 0};
  double f = 1.0;  // the tile's counts brought to the scan's time, as forgetting would
  marks.ForEachInFirst([&](TileKey key, int i, CellIndex c, const auto& in) {
    if (tile == nullptr || !(key == tile_key)) {
      tile_key = key;
      tile = window.at(key);
      f = tile != nullptr && forget ? self.ReadFactor(*tile, stamp) : 1.0;
    }
    if (tile == nullptr) return;
    float& a = tile->a()[i];
    float& b = tile->b()[i];
    if (a == 0.0f && b == 0.0f) return;
    // Beyond l only obstacle evidence is suspect: ground evidence there was learnt from the
    // cell's own surroundings, not only from the forgotten surface.
    if (!in(kWithinL)) {
      const double an = f == 1.0 ? a : static_cast<float>(static_cast<double>(a) * f);
      const double bn = f == 1.0 ? b : static_cast<float>(static_cast<double>(b) * f);
      if (p.alpha0 + an < p.trav_threshold * (p.alpha0 + p.beta0 + an + bn)) return;
    }
    if (forget) {
      self.Advance(*tile, stamp);
      f = 1.0;
    }
    a = b = 0.0f;
    tile->MarkCellChanged(i);
    if (touched.empty() || touched.back() != tile) touched.push_back(tile);
    out.push_back(c);
  });
  return out;
}

ScanIntegrator::Pass::FreeSpace ScanIntegrator::Pass::ApplyFreeSpace(const PreparedScan& scan,
                                                                     ScanReport& report) const {
  FreeSpace out;
  std::vector<TileKey>& cleared = out.cleared;
  if (self.params_.dynamics != Dynamics::kOn || !scan.has_sensor) return out;
  std::vector<ObservedCell> appeared;
  std::vector<CellIndex> risen;
  const std::vector<std::pair<CellIndex, int>> contradicted =
      CountContradictions(scan, appeared, risen);
  KeepGroundUnder(scan, appeared);
  // Every tile this changes beyond the write tiles is stamped and reported like them (it must be
  // checkpointed before it can be evicted).
  std::vector<const Tile*> touched;
  std::vector<CellIndex> forgotten;
  // The cut before the reset: the reset zeroes the contradicted cells' Beta counts either way.
  CutContradicted(contradicted, touched, forgotten);
  out.relearn = GroundLeftBy(forgotten, touched);
  ResetBetaNear(contradicted, touched);
  ResetBetaBesideRisen(risen, touched);
  report.contradicted_cells = contradicted.size();
  read_tile = nullptr;  // a clear tile read above may have been brought to the scan's time
  std::sort(touched.begin(), touched.end());
  for (const TileKey& key : scan.clear_tiles) {
    const Tile* tile = window.at(key);
    if (tile != nullptr && std::binary_search(touched.begin(), touched.end(), tile)) {
      cleared.push_back(key);
    }
  }
  return out;
}

// ---- 1. Elevation ----

template <bool kSecondMoment>
void ScanIntegrator::Pass::AddPlaneElevation(const PreparedScan& scan) const {
  const KernelStencil& ks = self.kernel_;
  const double w_cap = self.caps_.w;
  for (const ObservedCell& oc : scan.cells) {
    const double y = oc.y;
    ForEachKernelRun(oc.cell, [&](Tile& tile, int start, const double* k, const float*, int len) {
      internal::AddPlaneRun<kSecondMoment>(tile, start, len, ks, k, GainOf(tile), y);
      if (w_cap > 0) internal::CapElevationPlane(tile, start, len, w_cap);
    });
    // The cell's own observations, apart: its elevation is theirs (docs/semantics.md). (The
    // stencil's centre: its block is marked.)
    Tile& own = *TileAt(oc.cell);
    const int i = self.geometry_.LocalIndex(oc.cell);
    const double g = GainOf(own);
    own.plane(Tile::kOwnW)[i] += g;
    own.plane(Tile::kOwnS)[i] += g * y;
    if (w_cap > 0) internal::CapElevationPlane(own, i, 1, w_cap);
  }
}

// kSecondMoment: dynamics (Q kept, weights capped); kGain: forgetting (a late scan's
// contribution to a tile already at a later time is aged by Gain).
template <bool kSecondMoment, bool kGain>
void ScanIntegrator::Pass::AddKernelElevation(const PreparedScan& scan) const {
  const double w_cap = self.caps_.w;
  for (const ObservedCell& oc : scan.cells) {
    const double y = oc.y, yy = kSecondMoment ? oc.y * oc.y : 0.0;
    ForEachKernelRun(oc.cell, [&](Tile& tile, int start, const double* k, const float*, int len) {
      double* w = tile.w().data() + start;
      double* s = tile.s().data() + start;
      double* q = tile.q().data() + start;
      const double g = kGain ? GainOf(tile) : 1.0;
      internal::AddElevationRun<kSecondMoment, kGain>(w, s, q, k, len, g, y, yy);
      if constexpr (kSecondMoment) internal::CapElevation(w, s, q, len, w_cap);
    });
  }
}

// Baseline and one-step: the running mean of the cell's own observations.
void ScanIntegrator::Pass::AddRawElevation(const PreparedScan& scan) const {
  const bool dynamic = self.params_.dynamics == Dynamics::kOn;
  for (const ObservedCell& oc : scan.cells) {
    Tile* tile = TileAt(oc.cell);
    const int i = self.geometry_.LocalIndex(oc.cell);
    const double g = GainOf(*tile);  // 1 without forgetting: the sums are unchanged
    tile->MarkCellChanged(i);
    tile->w()[i] += g;
    tile->s()[i] += g * oc.y;
    if (dynamic) {
      tile->q()[i] += g * oc.y * oc.y;
      internal::CapElevation(&tile->w()[i], &tile->s()[i], &tile->q()[i], 1, self.caps_.w);
    }
  }
}

void ScanIntegrator::Pass::AddElevation(const PreparedScan& scan) const {
  const Method method = self.params_.method;
  const bool dynamic = self.params_.dynamics == Dynamics::kOn;
  if (KeepsPlaneMoments(method)) {
    dynamic ? AddPlaneElevation<true>(scan) : AddPlaneElevation<false>(scan);
  } else if (!InfersElevation(method)) {
    AddRawElevation(scan);
  } else if (!dynamic) {
    AddKernelElevation<false, false>(scan);  // forgetting needs dynamics
  } else if (forget) {
    AddKernelElevation<true, true>(scan);
  } else {
    AddKernelElevation<true, false>(scan);
  }
}

// ---- 2. Training values ----

// bgk-trav's training cells: every known cell within l of an observed cell, each once, in
// canonical order (tile by tile, row-major).
std::vector<CellIndex> ScanIntegrator::Pass::KernelReachKnownCells(const PreparedScan& scan) const {
  std::unordered_map<const Tile*, std::vector<uint8_t>> marks;
  for (const TileKey& key : scan.write_tiles) {
    marks[window.at(key)].assign(static_cast<size_t>(T) * T, 0);
  }
  for (const ObservedCell& oc : scan.cells) {
    ForEachKernelRun(oc.cell, [&](Tile& tile, int start, const double*, const float*, int len) {
      std::fill_n(marks[&tile].begin() + start, len, uint8_t{1});
    });
  }
  std::vector<CellIndex> out;
  for (const TileKey& key : scan.write_tiles) {
    const Tile* tile = window.at(key);
    const std::vector<uint8_t>& m = marks[tile];
    const CellIndex origin = self.geometry_.TileOrigin(key);
    for (int i = 0; i < tile->cell_count(); ++i) {
      if (m[i] && tile->w()[i] > 0.0) out.push_back({origin.x + i % T, origin.y + i / T});
    }
  }
  return out;
}

std::vector<std::pair<CellIndex, float>> ScanIntegrator::Pass::TrainingValues(
    const PreparedScan& scan, internal::TileSlabs& heights) const {
  std::vector<PatchPoint> patch;
  patch.reserve(self.neighbourhood_.size());
  std::vector<std::pair<CellIndex, float>> values;
  const auto add = [&](CellIndex c) {
    const float v = ValueAt(c, patch, heights);
    if (!std::isnan(v)) values.emplace_back(c, v);
  };
  if (self.params_.method == Method::kBgkTrav) {
    for (const CellIndex& c : KernelReachKnownCells(scan)) add(c);
  } else {
    values.reserve(scan.cells.size());
    // Beyond the paper: a cell whose own points span more than a traversable cell can is a
    // face, v = 1, whatever its neighbours (a vehicle's face over ground the map forgot).
    const double limit_mm = self.params_.dynamics == Dynamics::kOn
                                ? InCellStepLimit(self.params_) * 1000.0
                                : std::numeric_limits<double>::infinity();
    for (const ObservedCell& oc : scan.cells) {
      if (oc.span_mm > limit_mm) {
        values.emplace_back(oc.cell, 1.0f);
      } else {
        add(oc.cell);
      }
    }
  }
  return values;
}

// ---- 3. Traversability ----

template <bool kGain>
void ScanIntegrator::Pass::SpreadValue(CellIndex cell, float v) const {
  const float va = v, vb = 1.0f - v;
  const float ab_cap = self.caps_.ab;
  ForEachKernelRun(cell, [&](Tile& tile, int start, const double*, const float* k, int len) {
    float* a = tile.a().data() + start;
    float* b = tile.b().data() + start;
    const float g = kGain ? static_cast<float>(GainOf(tile)) : 1.0f;
    internal::AddBetaRun<kGain>(a, b, k, len, g, va, vb);
    if (ab_cap > 0) internal::CapBeta(a, b, len, ab_cap);
  });
  const float direct = self.direct_weight_;
  if (direct > 0.0f) {
    // bgk-obstacle: the cell's own evidence weighs as much as its whole neighbourhood's, so an
    // obstacle seen at a cell is not averaged away by the ground seen around it. (The stencil's
    // centre: its block is marked.)
    Tile* tile = TileAt(cell);
    const int i = self.geometry_.LocalIndex(cell);
    const float dg = direct * static_cast<float>(GainOf(*tile));
    tile->a()[i] += dg * va;
    tile->b()[i] += dg * vb;
    if (ab_cap > 0) internal::CapBeta(&tile->a()[i], &tile->b()[i], 1, ab_cap);
  }
}

void ScanIntegrator::Pass::AddTraversability(
    const std::vector<std::pair<CellIndex, float>>& values) const {
  if (!InfersTraversability(self.params_.method)) {
    for (const auto& [cell, v] : values) {
      Tile* tile = TileAt(cell);
      const int i = self.geometry_.LocalIndex(cell);
      tile->MarkCellChanged(i);
      tile->a()[i] = v;
      tile->b()[i] = 1.0f - v;
    }
    return;
  }
  for (const auto& [cell, v] : values)
    forget ? SpreadValue<true>(cell, v) : SpreadValue<false>(cell, v);
}

// Beyond the paper: ground beside a forgotten object that this scan's values left no counts
// re-learns from the surface left around it, where that surface crosses no critical value, at
// the weight of the elevations it rests on (docs/semantics.md, "Dynamics" 4). Its tile was reset
// (GroundLeftBy): it is reported.
void ScanIntegrator::Pass::RelearnGroundLeft(const std::vector<CellIndex>& relearn,
                                             internal::TileSlabs& heights) const {
  if (relearn.empty()) return;
  std::vector<PatchPoint> patch;
  patch.reserve(self.neighbourhood_.size());
  const float ab_cap = self.caps_.ab;
  const double full_kernel = FullKernelWeight(self.params_);
  for (const CellIndex& c : relearn) {
    Tile* tile = TileAt(c);
    const int i = self.geometry_.LocalIndex(c);
    float& a = tile->a()[i];
    float& b = tile->b()[i];
    if (a != 0.0f || b != 0.0f) continue;
    const float v = ValueAt(c, patch, heights);
    if (!(v < 1.0f)) continue;  // an obstacle, or no value (NaN)
    tile->MarkCellChanged(i);
    // As much as the elevations it rests on: the cell's own weight, at least one observation's
    // and at most one full-kernel observation's (what one scan seeing the surface would teach).
    const double weight = std::clamp(tile->w()[i], 1.0, full_kernel);
    const float g = static_cast<float>(GainOf(*tile) * weight);
    a = g * v;
    b = g * (1.0f - v);
    if (ab_cap > 0) internal::CapBeta(&a, &b, 1, ab_cap);
  }
}

// ---- 4. The robot's footprint ----

// Each cell under the robot gains footprint_weight of an observation of ground at footprint_y,
// and as much traversable evidence; at the cell only, so a real return there outweighs it
// (semantics "Dynamics").
void ScanIntegrator::Pass::AddFootprint(const PreparedScan& scan) const {
  const MapParams& p = self.params_;
  const double y = scan.footprint_y;
  for (const CellIndex& c : scan.footprint_cells) {
    Tile* tile = TileAt(c);
    const int i = self.geometry_.LocalIndex(c);
    const double wf = p.footprint_weight * GainOf(*tile);
    const float bf = static_cast<float>(wf);
    tile->MarkCellChanged(i);
    double* w = &tile->w()[i];
    double* s = &tile->s()[i];
    double* q = &tile->q()[i];
    *w += wf;
    *s += wf * y;
    *q += wf * y * y;
    // At the cell itself (u = v = 0): of the plane moments, only its own sums gain.
    if (tile->has_plane()) {
      tile->plane(Tile::kOwnW)[i] += wf;
      tile->plane(Tile::kOwnS)[i] += wf * y;
      if (self.caps_.w > 0) internal::CapElevationPlane(*tile, i, 1, self.caps_.w);
    } else {
      internal::CapElevation(w, s, q, 1, self.caps_.w);
    }
    // The vehicle's box: the robot stands on this cell now, so what said obstacle there (a
    // vehicle that drove off, a blend of its own body) is gone; the disk keeps A (semantics).
    if (scan.footprint_box) tile->a()[i] = 0.0f;
    if (InfersTraversability(p.method)) {
      tile->b()[i] += bf;
      if (self.caps_.ab > 0) internal::CapBeta(&tile->a()[i], &tile->b()[i], 1, self.caps_.ab);
    } else if (tile->a()[i] == 0.0f && tile->b()[i] == 0.0f) {
      tile->b()[i] = 1.0f;  // the latest direct value: none yet, the robot stands here
    }
  }
}

}  // namespace bgkmap
