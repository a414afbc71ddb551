#include "bgkmap/core/scan_integrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_features.h"
#include "footprint.h"
#include "ray_walk.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

constexpr float kNoValue = std::numeric_limits<float>::quiet_NaN();

}  // namespace

TileWindow::TileWindow(const std::vector<TileKey>& keys) {
  if (keys.empty()) return;
  min_ = max_ = keys.front();
  for (const TileKey& k : keys) {
    min_ = {std::min(min_.x, k.x), std::min(min_.y, k.y)};
    max_ = {std::max(max_.x, k.x), std::max(max_.y, k.y)};
  }
  width_ = static_cast<size_t>(int64_t{max_.x} - min_.x + 1);
  const size_t area = width_ * static_cast<size_t>(int64_t{max_.y} - min_.y + 1);
  if (area <= 4 * keys.size() + 4096) {
    dense_.assign(area, nullptr);
  } else {
    for (const TileKey& k : keys) sparse_.emplace_back(k, nullptr);
  }
}

void TileWindow::set(TileKey k, Tile* t) {
  if (!dense_.empty()) {
    dense_[static_cast<size_t>(k.y - min_.y) * width_ + (k.x - min_.x)] = t;
    return;
  }
  auto it = std::lower_bound(sparse_.begin(), sparse_.end(), k,
                             [](const auto& e, const TileKey& key) { return e.first < key; });
  if (it != sparse_.end() && it->first == k) it->second = t;
}

Tile* TileWindow::SparseAt(TileKey k) const {
  auto it = std::lower_bound(sparse_.begin(), sparse_.end(), k,
                             [](const auto& e, const TileKey& key) { return e.first < key; });
  return it != sparse_.end() && it->first == k ? it->second : nullptr;
}

std::vector<CellIndex> DiskOffsets(double radius, double resolution) {
  const double limit = internal::NeighbourhoodLimit(radius, resolution);
  const int r = static_cast<int>(std::ceil(radius / resolution));
  std::vector<CellIndex> out;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (internal::InNeighbourhood(dx, dy, limit)) out.push_back({dx, dy});
    }
  }
  return out;
}

ScanIntegrator::ScanIntegrator(const MapParams& params)
    : params_(params),
      geometry_(params.resolution, params.tile_size),
      kernel_(params.resolution, params.kernel_length),
      neighbourhood_(DiskOffsets(params.robot_radius, params.resolution)),
      neighbourhood_radius_(static_cast<int>(std::ceil(params.robot_radius / params.resolution))) {
  if (params.method == Method::kBgkObstacle) {
    for (int r = 0; r < kernel_.row_count(); ++r) {
      for (int j = 0; j <= 2 * kernel_.half_width(r); ++j)
        direct_weight_ += kernel_.row_weights(r)[j];
    }
  }
  if (params.dynamics == Dynamics::kOn) {
    // A "full-kernel observation" is every cell within l observed once.
    double full_w = 0.0;
    float full_ab = 0.0f;
    for (int r = 0; r < kernel_.row_count(); ++r) {
      for (int j = 0; j <= 2 * kernel_.half_width(r); ++j) {
        full_w += kernel_.row_weights_double(r)[j];
        full_ab += kernel_.row_weights(r)[j];
      }
    }
    if (!InfersElevation(params.method)) full_w = 1.0;  // raw elevation: one per observation
    caps_.w = params.max_confidence_scans * full_w;
    caps_.forget_below = 0.1 * full_w;
    // Direct methods keep the latest v (a + b = 1): nothing accumulates.
    if (InfersTraversability(params.method)) {
      caps_.ab = static_cast<float>(params.max_confidence_scans * full_ab);
    }
    half_life_ns_ = params.half_life_s * 1e9;
  }
}

double ScanIntegrator::DecayFactor(int64_t dt_ns) const {
  if (!(half_life_ns_ > 0) || dt_ns <= 0) return 1.0;
  return std::exp2(-static_cast<double>(dt_ns) / half_life_ns_);
}

void ScanIntegrator::Advance(Tile& tile, int64_t t) const {
  if (!(half_life_ns_ > 0) || t == 0 || t <= tile.stamp_ns()) return;
  if (tile.stamp_ns() != 0) tile.Scale(DecayFactor(t - tile.stamp_ns()));
  tile.set_stamp_ns(t);
}

double ScanIntegrator::Gain(const Tile& tile, int64_t t) const {
  if (t == 0 || tile.stamp_ns() <= t) return 1.0;
  return DecayFactor(tile.stamp_ns() - t);
}

double ScanIntegrator::ReadFactor(const Tile& tile, int64_t t) const {
  if (t == 0 || tile.stamp_ns() == 0 || tile.stamp_ns() >= t) return 1.0;
  return DecayFactor(t - tile.stamp_ns());
}

namespace {

// Scales the cells of [w, w + len) whose elevation weight passed `cap` back onto it.
inline void CapElevation(double* w, double* s, double* q, int len, double cap) {
  for (int j = 0; j < len; ++j) {
    if (w[j] > cap) {
      const double f = cap / w[j];
      w[j] = cap;
      s[j] *= f;
      q[j] *= f;
    }
  }
}

// The mean of cell i's own observations in a bgk-ll tile, NaN if it has none (a ratio: a read
// factor would cancel).
inline double OwnHeight(const Tile& tile, int i) {
  const double own_w = tile.plane(Tile::kOwnW)[i];
  return own_w > 0.0 ? tile.plane(Tile::kOwnS)[i] / own_w
                     : std::numeric_limits<double>::quiet_NaN();
}

// CapElevation for a tile with plane moments: the cell's moments scale with its weight.
inline void CapElevationPlane(Tile& tile, int start, int len, double cap) {
  double* w = tile.w().data() + start;
  for (int j = 0; j < len; ++j) {
    if (w[j] > cap) tile.ScaleCell(start + j, cap / w[j]);
  }
}

// Adds one observation y, with gain g, to a run of a bgk-ll tile's cells: the kernel sums and
// the plane moments (Q only with dynamics: without, it stays 0 and is not touched).
template <bool kSecondMoment>
inline void AddPlaneRun(Tile& tile, int start, int len, const KernelStencil& ks, const double* k,
                        double g, double y) {
  double* __restrict w = tile.w().data() + start;
  double* __restrict s = tile.s().data() + start;
  double* __restrict q = tile.q().data() + start;
  double* __restrict su = tile.plane(Tile::kSu).data() + start;
  double* __restrict sv = tile.plane(Tile::kSv).data() + start;
  double* __restrict suu = tile.plane(Tile::kSuu).data() + start;
  double* __restrict suv = tile.plane(Tile::kSuv).data() + start;
  double* __restrict svv = tile.plane(Tile::kSvv).data() + start;
  double* __restrict suy = tile.plane(Tile::kSuy).data() + start;
  double* __restrict svy = tile.plane(Tile::kSvy).data() + start;
  const double* ku = ks.moments_at(0, k);
  const double* kv = ks.moments_at(1, k);
  const double* kuu = ks.moments_at(2, k);
  const double* kuv = ks.moments_at(3, k);
  const double* kvv = ks.moments_at(4, k);
  const double gy = g * y, gyy = gy * y;
  for (int j = 0; j < len; ++j) {
    w[j] += k[j] * g;
    s[j] += k[j] * gy;
    if constexpr (kSecondMoment) q[j] += k[j] * gyy;
    su[j] += ku[j] * g;
    sv[j] += kv[j] * g;
    suu[j] += kuu[j] * g;
    suv[j] += kuv[j] * g;
    svv[j] += kvv[j] * g;
    suy[j] += ku[j] * gy;
    svy[j] += kv[j] * gy;
  }
}

// The float sum of a scaled pair can land an ulp above `cap`: the slack makes capping
// idempotent, so a merge re-capping an already capped map changes nothing.
inline void CapBeta(float* a, float* b, int len, float cap) {
  const float limit = cap * (1.0f + 1e-5f);
  for (int j = 0; j < len; ++j) {
    const float sum = a[j] + b[j];
    if (sum > limit) {
      const float f = cap / sum;
      a[j] *= f;
      b[j] *= f;
    }
  }
}

}  // namespace

void ScanIntegrator::Saturate(Tile& tile) const {
  const int n = tile.cell_count();
  if (caps_.w > 0 && tile.has_plane()) {
    CapElevationPlane(tile, 0, n, caps_.w);
  } else if (caps_.w > 0) {
    CapElevation(tile.w().data(), tile.s().data(), tile.q().data(), n, caps_.w);
  }
  if (caps_.ab > 0) CapBeta(tile.a().data(), tile.b().data(), n, caps_.ab);
}

// The per-scan work, with the scan's window and parameters at hand.
struct ScanIntegrator::Impl {
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
  // skipped; otherwise every tile must be there.
  template <bool kSkipAbsent = false, typename RowFn>
  void ForEachKernelRun(CellIndex c, RowFn&& row) const {
    const KernelStencil& k = self.kernel_;
    const int R = k.radius();
    const int lx = FloorMod(c.x, T), ly = FloorMod(c.y, T);
    if (lx >= R && lx + R < T && ly >= R && ly + R < T) {  // fast path: one tile
      Tile* tile = TileAt(c);
      if (kSkipAbsent && tile == nullptr) return;
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
          row(*tile, row_y * T + (x - key.x * T), k.row_weights_double(r) + off,
              k.row_weights(r) + off, seg_end - x + 1);
        }
        x = seg_end + 1;
      }
    }
  }

  // The top of what cell i of `tile` (read with factor f) has seen, for the free-space test:
  // its height plus the deviation of the observations within l about their kernel mean. The
  // height is the kernel mean, or a bgk-ll cell's own observations' mean where it has any: the
  // cheap reads, as a ray crosses many cells. False for an unknown cell.
  bool SeenTop(const Tile& tile, int i, double f, double* top) const {
    const double w = f * tile.w()[i];
    if (!(w > 0.0)) return false;
    const MapParams& p = self.params_;
    const double s = f * tile.s()[i];
    double height = (p.lambda * p.prior_mean + s) / (p.lambda + w);
    if (tile.has_plane() && !std::isnan(OwnHeight(tile, i))) height = OwnHeight(tile, i);
    *top = height + std::sqrt(Disagreement(w, s, f * tile.q()[i]));
    return true;
  }

  // Elevation of a known cell, NaN otherwise.
  double Elevation(CellIndex c) const {
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

  // The cells this scan contradicts, sorted, each once per piece of evidence (semantics
  // "Dynamics"), read from the map before the scan changes it: a return clearly above a cell's
  // elevation (something appeared), and a ray passing clearly below one on its way to its return
  // (what was there has gone).
  std::vector<CellIndex> Contradicted(const PreparedScan& scan) const {
    std::vector<CellIndex> out;
    const MapParams& p = self.params_;
    const double margin = p.clear_margin;
    for (const ObservedCell& oc : scan.cells) {
      const double m = Elevation(oc.cell);
      if (oc.y > m + margin) out.push_back(oc.cell);  // false for NaN (unknown)
    }
    if (p.clear_ray_length > 0) {
      const double res = p.resolution;
      const double sx = scan.sensor_x / res, sy = scan.sensor_y / res;
      const double length = p.clear_ray_length / res;
      // Cells within l of the return are skipped: there the kernel blends the return's own
      // surface into its neighbours, and a ray that hit a face would "contradict" the blend.
      const double skip = p.kernel_length / res;
      TileKey last_key{0, 0};
      const Tile* last_tile = nullptr;
      double last_f = 1.0;
      bool have_last = false;
      for (const ObservedCell& oc : scan.cells) {
        const double dist = std::hypot(sx - (oc.cell.x + 0.5), sy - (oc.cell.y + 0.5));
        if (!(dist > skip)) continue;
        const double rise = (scan.sensor_z - oc.y) / dist;  // ray height gained per cell
        internal::WalkRayBack(oc.cell, sx, sy, length, [&](CellIndex c, double t) {
          if (t < skip) return;
          const TileKey key = self.geometry_.TileOf(c);
          if (!have_last || key != last_key) {  // the footprint holds every tile a ray crosses
            last_key = key;
            last_tile = window.at(key);
            last_f = last_tile != nullptr ? ReadFactorOf(*last_tile) : 1.0;
            have_last = true;
          }
          if (last_tile == nullptr) return;
          const int i = self.geometry_.LocalIndex(c);
          // The top of what the cell has seen: its elevation plus its disagreement's deviation,
          // so an old object's remains, mixed with new ground, still stand above a grazing ray.
          double top;
          if (!SeenTop(*last_tile, i, last_f, &top)) return;
          if (oc.y + rise * t < top - margin) out.push_back(c);
        });
      }
    }
    std::sort(out.begin(), out.end());
    return out;
  }

  // The height v is computed from at cell c: its elevation, or for bgk-ll its own observations'
  // mean (NaN if it has none).
  double FeatureHeight(CellIndex c) const {
    const Tile* tile = TileAt(c);
    if (tile == nullptr || !tile->has_plane()) return Elevation(c);
    return OwnHeight(*tile, self.geometry_.LocalIndex(c));
  }

  // Traversability training value v at `c` from the current elevations (semantics 6), or NaN
  // with fewer than three known cells within the robot radius.
  float ValueAt(CellIndex c, std::vector<PatchPoint>& patch) const {
    patch.clear();
    const MapParams& p = self.params_;
    const double res = p.resolution;
    const int R = self.neighbourhood_radius_;
    const int lx = FloorMod(c.x, T), ly = FloorMod(c.y, T);
    if (lx >= R && lx + R < T && ly >= R && ly + R < T) {  // fast path: one tile
      const Tile* tile = TileAt(c);
      const double* w = tile->w().data();
      const double* s = tile->s().data();
      const int centre = ly * T + lx;
      for (const CellIndex& o : self.neighbourhood_) {
        const int i = centre + o.y * T + o.x;
        if (!(w[i] > 0.0)) continue;
        // bgk-ll: v from the data, the cells' own observations, not from the fitted surface
        // (which fills unobserved cells, e.g. behind an occluding edge, with planes that would
        // read as steps).
        const double z = tile->has_plane() ? OwnHeight(*tile, i)
                                           : (p.lambda * p.prior_mean + s[i]) / (p.lambda + w[i]);
        if (!std::isnan(z)) patch.push_back({o.x * res, o.y * res, z});
      }
    } else {
      for (const CellIndex& o : self.neighbourhood_) {
        const double z = FeatureHeight({c.x + o.x, c.y + o.y});
        if (!std::isnan(z)) patch.push_back({o.x * res, o.y * res, z});
      }
    }
    if (patch.size() < 3) return kNoValue;
    return static_cast<float>(TraversabilityValue(ComputeFeatures(patch), p));
  }
};

ScanReport ScanIntegrator::Integrate(const PreparedScan& scan, const TileWindow& window,
                                     uint64_t version) const {
  ScanReport report;
  report.counts = scan.counts;
  report.observed_cells = scan.cells.size();
  const bool forget = forgetting() && scan.stamp_ns != 0;
  const Impl impl{*this, window, params_.tile_size, scan.stamp_ns, forget};
  const Method method = params_.method;

  const bool dynamic = params_.dynamics == Dynamics::kOn;
  const auto t0 = Clock::now();
  // Forgetting: the tiles the scan writes are brought to its time first; the others it may
  // change when it does (Advance is idempotent); the ones it only reads are read as of it.
  if (forget) {
    for (const TileKey& key : scan.write_tiles) Advance(*window.at(key), scan.stamp_ns);
  }
  std::vector<TileKey> cleared;  // clear_tiles the evidence changed
  // 0. Free-space evidence (dynamics): contradicted cells keep clear_decay of their statistics.
  if (dynamic && scan.has_sensor) {
    // Each contradicted cell once, with the number of rays (and returns) that contradict it.
    std::vector<std::pair<CellIndex, int>> contradicted;
    for (const CellIndex& c : impl.Contradicted(scan)) {
      if (!contradicted.empty() && contradicted.back().first == c) {
        ++contradicted.back().second;
      } else {
        contradicted.emplace_back(c, 1);
      }
    }
    // Every tile this changes beyond the write tiles is stamped and reported like them (it must
    // be checkpointed before it can be evicted).
    std::vector<const Tile*> touched;
    // The traversability evidence within l of a contradicted cell was learnt from a surface that
    // is not there any more: it is re-learnt from this scan on.
    for (const auto& [c, count] : contradicted) {
      impl.ForEachKernelRun<true>(c,
                                  [&](Tile& tile, int start, const double*, const float*, int len) {
                                    float* a = tile.a().data() + start;
                                    float* b = tile.b().data() + start;
                                    bool any = false;
                                    for (int j = 0; j < len; ++j)
                                      any |= (a[j] != 0.0f) | (b[j] != 0.0f);
                                    if (!any) return;
                                    if (forget) Advance(tile, scan.stamp_ns);
                                    std::fill_n(a, len, 0.0f);
                                    std::fill_n(b, len, 0.0f);
                                    if (touched.empty() || touched.back() != &tile)
                                      touched.push_back(&tile);
                                  });
    }
    for (const auto& [c, count] : contradicted) {
      Tile& tile = *impl.TileAt(c);
      if (forget) Advance(tile, scan.stamp_ns);
      const int i = geometry_.LocalIndex(c);
      // Independent rays are independent evidence: each keeps clear_decay of what is left.
      double keep = 1.0;
      for (int k = 0; k < count && keep > 0.0; ++k) keep *= params_.clear_decay;
      tile.ScaleCell(i, keep);
      // What is left is less than a tenth of one observation: forgotten, the cell is unknown
      // again until something is seen there (a removed object over ground no ray reaches).
      if (tile.w()[i] < caps_.forget_below) tile.ClearCell(i);
      if (touched.empty() || touched.back() != &tile) touched.push_back(&tile);
    }
    report.contradicted_cells = contradicted.size();
    impl.read_tile = nullptr;  // a clear tile read above may have been brought to the scan's time
    std::sort(touched.begin(), touched.end());
    for (const TileKey& key : scan.clear_tiles) {
      const Tile* tile = window.at(key);
      if (tile != nullptr && std::binary_search(touched.begin(), touched.end(), tile)) {
        cleared.push_back(key);
      }
    }
  }

  // 1. Elevation (semantics 4; raw running mean for baseline and one-step; plane moments too
  // for bgk-ll).
  const double w_cap = caps_.w;
  if (KeepsPlaneMoments(method)) {
    const KernelStencil& ks = kernel_;
    for (const ObservedCell& oc : scan.cells) {
      const double y = oc.y;
      impl.ForEachKernelRun(oc.cell,
                            [&impl, &ks, y, w_cap, dynamic](Tile& tile, int start, const double* k,
                                                            const float*, int len) {
                              const double g = impl.GainOf(tile);  // 1 without forgetting
                              if (dynamic) {
                                AddPlaneRun<true>(tile, start, len, ks, k, g, y);
                              } else {
                                AddPlaneRun<false>(tile, start, len, ks, k, g, y);
                              }
                              if (w_cap > 0) CapElevationPlane(tile, start, len, w_cap);
                            });
      // The cell's own observations, apart: its elevation is theirs (docs/semantics.md).
      Tile& own = *impl.TileAt(oc.cell);
      const int i = geometry_.LocalIndex(oc.cell);
      const double g = impl.GainOf(own);
      own.plane(Tile::kOwnW)[i] += g;
      own.plane(Tile::kOwnS)[i] += g * y;
      if (w_cap > 0) CapElevationPlane(own, i, 1, w_cap);
    }
  } else if (InfersElevation(method) && !dynamic) {
    for (const ObservedCell& oc : scan.cells) {
      const double y = oc.y;
      impl.ForEachKernelRun(oc.cell,
                            [y](Tile& tile, int start, const double* k, const float*, int len) {
                              double* __restrict w = tile.w().data() + start;
                              double* __restrict s = tile.s().data() + start;
                              for (int j = 0; j < len; ++j) {
                                w[j] += k[j];
                                s[j] += k[j] * y;
                              }
                            });
    }
  } else if (InfersElevation(method) && forget) {
    // A late scan's contribution to a tile already at a later time is aged by Gain.
    for (const ObservedCell& oc : scan.cells) {
      const double y = oc.y, yy = oc.y * oc.y;
      impl.ForEachKernelRun(oc.cell, [&impl, y, yy, w_cap](Tile& tile, int start, const double* k,
                                                           const float*, int len) {
        const double g = impl.GainOf(tile);
        double* __restrict w = tile.w().data() + start;
        double* __restrict s = tile.s().data() + start;
        double* __restrict q = tile.q().data() + start;
        for (int j = 0; j < len; ++j) {
          const double kg = k[j] * g;
          w[j] += kg;
          s[j] += kg * y;
          q[j] += kg * yy;
        }
        CapElevation(w, s, q, len, w_cap);
      });
    }
  } else if (InfersElevation(method)) {
    for (const ObservedCell& oc : scan.cells) {
      const double y = oc.y, yy = oc.y * oc.y;
      impl.ForEachKernelRun(
          oc.cell, [y, yy, w_cap](Tile& tile, int start, const double* k, const float*, int len) {
            double* __restrict w = tile.w().data() + start;
            double* __restrict s = tile.s().data() + start;
            double* __restrict q = tile.q().data() + start;
            for (int j = 0; j < len; ++j) {
              w[j] += k[j];
              s[j] += k[j] * y;
              q[j] += k[j] * yy;
            }
            CapElevation(w, s, q, len, w_cap);
          });
    }
  } else {
    for (const ObservedCell& oc : scan.cells) {
      Tile* tile = impl.TileAt(oc.cell);
      const int i = geometry_.LocalIndex(oc.cell);
      const double g = impl.GainOf(*tile);  // 1 without forgetting: the sums are unchanged
      tile->w()[i] += g;
      tile->s()[i] += g * oc.y;
      if (dynamic) {
        tile->q()[i] += g * oc.y * oc.y;
        CapElevation(&tile->w()[i], &tile->s()[i], &tile->q()[i], 1, w_cap);
      }
    }
  }

  // 2. Traversability training values (semantics 6).
  const auto t1 = Clock::now();
  std::vector<PatchPoint> patch;
  patch.reserve(neighbourhood_.size());
  std::vector<std::pair<CellIndex, float>> values;  // cells where v was computed
  if (method == Method::kBgkTrav) {
    // Every known cell within l of an observed cell, each once, in canonical order.
    std::unordered_map<const Tile*, std::vector<uint8_t>> marks;
    for (const TileKey& key : scan.write_tiles) {
      marks[window.at(key)].assign(static_cast<size_t>(params_.tile_size) * params_.tile_size, 0);
    }
    for (const ObservedCell& oc : scan.cells) {
      impl.ForEachKernelRun(oc.cell,
                            [&](Tile& tile, int start, const double*, const float*, int len) {
                              std::fill_n(marks[&tile].begin() + start, len, uint8_t{1});
                            });
    }
    for (const TileKey& key : scan.write_tiles) {
      const Tile* tile = window.at(key);
      const std::vector<uint8_t>& m = marks[tile];
      const CellIndex origin = geometry_.TileOrigin(key);
      for (int i = 0; i < tile->cell_count(); ++i) {
        if (!m[i] || !(tile->w()[i] > 0.0)) continue;
        const CellIndex c{origin.x + i % params_.tile_size, origin.y + i / params_.tile_size};
        const float v = impl.ValueAt(c, patch);
        if (!std::isnan(v)) values.emplace_back(c, v);
      }
    }
  } else {
    values.reserve(scan.cells.size());
    for (const ObservedCell& oc : scan.cells) {
      const float v = impl.ValueAt(oc.cell, patch);
      if (!std::isnan(v)) values.emplace_back(oc.cell, v);
    }
  }
  report.feature_cells = values.size();

  // 3. Traversability: Beta pseudo-counts spread by the kernel (semantics 7), or the latest
  // direct value for baseline and bgk-trav.
  const auto t2 = Clock::now();
  if (InfersTraversability(method)) {
    const float ab_cap = caps_.ab;
    const float direct = direct_weight_;
    for (const auto& [cell, v] : values) {
      const float va = v, vb = 1.0f - v;
      if (!forget) {
        impl.ForEachKernelRun(
            cell, [va, vb, ab_cap](Tile& tile, int start, const double*, const float* k, int len) {
              float* __restrict a = tile.a().data() + start;
              float* __restrict b = tile.b().data() + start;
              for (int j = 0; j < len; ++j) {
                a[j] += k[j] * va;
                b[j] += k[j] * vb;
              }
              if (ab_cap > 0) CapBeta(a, b, len, ab_cap);
            });
      } else {
        impl.ForEachKernelRun(cell, [&impl, va, vb, ab_cap](Tile& tile, int start, const double*,
                                                            const float* k, int len) {
          const float g = static_cast<float>(impl.GainOf(tile));
          float* __restrict a = tile.a().data() + start;
          float* __restrict b = tile.b().data() + start;
          for (int j = 0; j < len; ++j) {
            const float kg = k[j] * g;
            a[j] += kg * va;
            b[j] += kg * vb;
          }
          if (ab_cap > 0) CapBeta(a, b, len, ab_cap);
        });
      }
      if (direct > 0.0f) {
        // bgk-obstacle: the cell's own evidence weighs as much as its whole neighbourhood's, so
        // an obstacle seen at a cell is not averaged away by the ground seen around it.
        Tile* tile = impl.TileAt(cell);
        const int i = geometry_.LocalIndex(cell);
        const float dg = direct * static_cast<float>(impl.GainOf(*tile));
        tile->a()[i] += dg * va;
        tile->b()[i] += dg * vb;
        if (ab_cap > 0) CapBeta(&tile->a()[i], &tile->b()[i], 1, ab_cap);
      }
    }
  } else {
    for (const auto& [cell, v] : values) {
      Tile* tile = impl.TileAt(cell);
      const int i = geometry_.LocalIndex(cell);
      tile->a()[i] = v;
      tile->b()[i] = 1.0f - v;
    }
  }
  // 4. The robot's footprint (dynamics, sensor_height > 0): each cell under the robot gains
  // footprint_weight of an observation of ground at footprint_y, and as much traversable
  // evidence; at the cell only, so a real return there outweighs it (semantics "Dynamics").
  if (!scan.footprint_cells.empty()) {
    const double y = scan.footprint_y;
    for (const CellIndex& c : scan.footprint_cells) {
      Tile* tile = impl.TileAt(c);
      const int i = geometry_.LocalIndex(c);
      const double wf = params_.footprint_weight * impl.GainOf(*tile);
      const float bf = static_cast<float>(wf);
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
        if (caps_.w > 0) CapElevationPlane(*tile, i, 1, caps_.w);
      } else {
        CapElevation(w, s, q, 1, caps_.w);
      }
      if (InfersTraversability(method)) {
        tile->b()[i] += bf;
        if (caps_.ab > 0) CapBeta(&tile->a()[i], &tile->b()[i], 1, caps_.ab);
      } else if (tile->a()[i] == 0.0f && tile->b()[i] == 0.0f) {
        tile->b()[i] = 1.0f;  // the latest direct value: none yet, the robot stands here
      }
    }
  }
  const auto t3 = Clock::now();

  for (const TileKey& key : scan.write_tiles) window.at(key)->set_version(version);
  for (const TileKey& key : cleared) window.at(key)->set_version(version);
  if (cleared.empty()) {
    report.changed_tiles = scan.write_tiles;
  } else {
    std::merge(scan.write_tiles.begin(), scan.write_tiles.end(), cleared.begin(), cleared.end(),
               std::back_inserter(report.changed_tiles));
  }
  report.times = {Seconds(t0, t1), Seconds(t1, t2), Seconds(t2, t3)};
  return report;
}

}  // namespace bgkmap
