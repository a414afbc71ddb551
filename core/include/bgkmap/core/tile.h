// A square block of cells holding the map's additive sufficient statistics.
#pragma once

#include <cstdint>
#include <memory>
#include <span>

#include "bgkmap/core/grid.h"

namespace bgkmap {

// Per-cell statistics, stored as structure-of-arrays (32 bytes per cell):
//   w: elevation weight   W = sum k          (double: its rounding would bias S/W)
//   s: elevation moment   S = sum k*y        (double: y can be an absolute altitude)
//   q: second moment      Q = sum k*y^2      (double; kept with dynamics on, else 0): Q/W - (S/W)^2
//                         is how much the cell's observations disagree
//   a: traversability     A = sum k*v        (float: enters only a probability)
//   b: traversability     B = sum k*(1 - v)
// For methods that keep a directly computed v instead of inferring it (baseline, bgk-trav),
// a = v and b = 1 - v of the latest computation.
// Local-linear maps (bgk-ll) also keep, per cell, the plane moments of its kernel neighbourhood,
// with (u, v) the training cell's offset from this cell in metres, and the cell's own
// observations apart (72 more bytes per cell, double: y can be an absolute altitude):
//   sum k*u, k*v, k*u^2, k*u*v, k*v^2, k*u*y, k*v*y, own weight sum 1, own sum y  (Plane enum)
// Everything is additive: the statistics of two maps of the same parameters merge by summation.
class Tile {
 public:
  enum Plane { kSu = 0, kSv, kSuu, kSuv, kSvv, kSuy, kSvy, kOwnW, kOwnS };
  static constexpr int kPlaneMoments = 9;

  explicit Tile(int tile_size, bool plane_moments = false);
  Tile(const Tile& other);
  Tile& operator=(const Tile&) = delete;

  int tile_size() const { return size_; }
  int cell_count() const { return size_ * size_; }

  std::span<double> w() { return {w_.get(), n()}; }
  std::span<double> s() { return {s_.get(), n()}; }
  std::span<double> q() { return {q_.get(), n()}; }
  std::span<float> a() { return {a_.get(), n()}; }
  std::span<float> b() { return {b_.get(), n()}; }
  std::span<const double> w() const { return {w_.get(), n()}; }
  std::span<const double> s() const { return {s_.get(), n()}; }
  std::span<const double> q() const { return {q_.get(), n()}; }
  std::span<const float> a() const { return {a_.get(), n()}; }
  std::span<const float> b() const { return {b_.get(), n()}; }
  // Copies cell `local`'s plane moments to out[0..kPlaneMoments) (the tile must keep them).
  void PlaneOf(int local, double* out) const {
    for (int m = 0; m < kPlaneMoments; ++m) out[m] = p_[m * n() + local];
  }
  // The plane moments (null spans when the tile keeps none).
  bool has_plane() const { return p_ != nullptr; }
  std::span<double> plane(int m) { return {p_ ? p_.get() + m * n() : nullptr, p_ ? n() : 0}; }
  std::span<const double> plane(int m) const {
    return {p_ ? p_.get() + m * n() : nullptr, p_ ? n() : 0};
  }

  // A cell is known once it has elevation weight or traversability pseudo-counts.
  bool IsKnown(int local) const { return w_[local] > 0.0 || (a_[local] + b_[local]) > 0.0f; }
  // The known cells' count and bounding box in tile-local cells (0..tile_size-1; empty if
  // none), in one pass: the served map summarises every tile a scan changes.
  struct KnownCells {
    int count = 0;
    CellBox local_box;
  };
  KnownCells Known() const;
  int CountKnown() const { return Known().count; }
  CellBox KnownLocalBox() const { return Known().local_box; }
  bool Empty() const { return CountKnown() == 0; }

  // Adds another tile's statistics cell by cell (same size required).
  void Add(const Tile& other);
  void Clear();
  // Statistics and stamp, bitwise (not the version).
  bool operator==(const Tile& other) const;

  // Map version of the last scan or edit that changed this tile (0 = never).
  uint64_t version() const { return version_; }
  void set_version(uint64_t v) { version_ = v; }

  // Map time (ns, a scan stamp) the statistics are as of, with forgetting on (half_life_s > 0,
  // docs/semantics.md "Forgetting"); 0 without forgetting or before any stamped scan.
  int64_t stamp_ns() const { return stamp_ns_; }
  void set_stamp_ns(int64_t t) { stamp_ns_ = t; }

  // Multiplies every statistic of every cell by f (forgetting: the tile brought to a later
  // time). +0 stays +0.
  void Scale(double f);

  // Multiplies every statistic of cell `local` by f: the mean and the disagreement stay, the
  // confidence scales (saturation and free-space evidence, docs/semantics.md).
  void ScaleCell(int local, double f) {
    w_[local] *= f;
    s_[local] *= f;
    q_[local] *= f;
    if (p_) {
      for (int m = 0; m < kPlaneMoments; ++m) p_[m * n() + local] *= f;
    }
    a_[local] = static_cast<float>(a_[local] * f);
    b_[local] = static_cast<float>(b_[local] * f);
  }

  // Makes cell `local` unknown: every statistic +0 (not -0, which a scaling by 0 could leave and
  // which a merge would turn into +0).
  void ClearCell(int local) {
    w_[local] = s_[local] = q_[local] = 0.0;
    if (p_) {
      for (int m = 0; m < kPlaneMoments; ++m) p_[m * n() + local] = 0.0;
    }
    a_[local] = b_[local] = 0.0f;
  }

  static constexpr size_t kBytesPerCell = 3 * sizeof(double) + 2 * sizeof(float);
  static constexpr size_t kPlaneBytesPerCell = kPlaneMoments * sizeof(double);
  size_t bytes_per_cell() const { return kBytesPerCell + (p_ ? kPlaneBytesPerCell : 0); }

 private:
  size_t n() const { return static_cast<size_t>(size_) * size_; }
  int size_;
  uint64_t version_ = 0;
  int64_t stamp_ns_ = 0;
  std::unique_ptr<double[]> w_, s_, q_;
  std::unique_ptr<float[]> a_, b_;
  std::unique_ptr<double[]> p_;  // kPlaneMoments arrays of n(), or null
};

}  // namespace bgkmap
