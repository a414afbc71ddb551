// A square block of cells holding the map's additive sufficient statistics.
#pragma once

#include <bit>
#include <cassert>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile_blocks.h"

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
//
// Two forms, the same statistics bit for bit. Dense (the default, what the engine's kernels work
// on): every statistic an array over all cells. Packed (Pack(), for tiles nobody is changing): an
// occupancy bitmask of the cells and, in cell order, the values of only the cells with any
// nonzero bit (-0.0 is a nonzero bit pattern), so that a mostly empty tile holds little more
// than its known cells. The span accessors (w(), s(), q(), a(), b(), plane()) and every mutator
// except Clear() need a dense tile (asserted in debug builds): Unpack() first. Everything a
// reader does works on either form: the copy constructor (which keeps the form), CellAt(),
// PlaneOf(), IsKnown(), Known(), operator==, MemoryBytes(); a bulk reader takes a dense copy
// (copy, then Unpack()).
class Tile {
 public:
  enum Plane { kSu = 0, kSv, kSuu, kSuv, kSvv, kSuy, kSvy, kOwnW, kOwnS };
  static constexpr int kPlaneMoments = 9;

  explicit Tile(int tile_size, bool plane_moments = false);
  Tile(const Tile& other);
  Tile& operator=(const Tile&) = delete;
  // Becomes a copy of `other` in its form (version and stamp included); same size required.
  void Assign(const Tile& other);
  // A packed copy of `other`, of either form, without a dense copy in between (what a
  // checkpoint holds until it is written: the stored cells, not the tile's area).
  static std::unique_ptr<Tile> PackedCopy(const Tile& other);

  // The form (see above). Pack() and Unpack() keep the statistics bit for bit; each is a no-op
  // on a tile already in that form.
  bool is_packed() const { return w_ == nullptr; }
  void Pack();
  void Unpack();
  // Bytes this tile holds in its current form (its arrays and the Tile itself).
  size_t MemoryBytes() const;

  // One cell's statistics, in either form.
  struct CellStats {
    double w = 0.0, s = 0.0, q = 0.0;
    float a = 0.0f, b = 0.0f;
  };
  CellStats CellAt(int local) const {
    if (is_packed()) return PackedCellAt(local);
    return {w_[local], s_[local], q_[local], a_[local], b_[local]};
  }

  int tile_size() const { return size_; }
  int cell_count() const { return size_ * size_; }

  // Dense tiles only.
  std::span<double> w() { return {DenseOnly(w_.get()), n()}; }
  std::span<double> s() { return {DenseOnly(s_.get()), n()}; }
  std::span<double> q() { return {DenseOnly(q_.get()), n()}; }
  std::span<float> a() { return {DenseOnly(a_.get()), n()}; }
  std::span<float> b() { return {DenseOnly(b_.get()), n()}; }
  std::span<const double> w() const { return {DenseOnly(w_.get()), n()}; }
  std::span<const double> s() const { return {DenseOnly(s_.get()), n()}; }
  std::span<const double> q() const { return {DenseOnly(q_.get()), n()}; }
  std::span<const float> a() const { return {DenseOnly(a_.get()), n()}; }
  std::span<const float> b() const { return {DenseOnly(b_.get()), n()}; }
  // Copies cell `local`'s plane moments to out[0..kPlaneMoments) (the tile must keep them); in
  // either form.
  void PlaneOf(int local, double* out) const {
    if (is_packed()) return PackedPlaneOf(local, out);
    for (int m = 0; m < kPlaneMoments; ++m) out[m] = p_[m * n() + local];
  }
  // The plane moments (null spans when the tile keeps none; dense tiles only).
  bool has_plane() const { return plane_; }
  std::span<double> plane(int m) {
    return {plane_ ? DenseOnly(p_.get()) + m * n() : nullptr, plane_ ? n() : 0};
  }
  std::span<const double> plane(int m) const {
    return {plane_ ? DenseOnly(p_.get()) + m * n() : nullptr, plane_ ? n() : 0};
  }

  // A cell is known once it has elevation weight or traversability pseudo-counts (either form).
  bool IsKnown(int local) const {
    if (is_packed()) {
      const CellStats c = PackedCellAt(local);
      return c.w > 0.0 || (c.a + c.b) > 0.0f;
    }
    return w_[local] > 0.0 || (a_[local] + b_[local]) > 0.0f;
  }
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

  // Adds another tile's statistics cell by cell (same size required; `other` in either form).
  void Add(const Tile& other);
  // Every statistic +0; a packed tile becomes dense.
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
  // time). +0 stays +0. Marks every block changed.
  void Scale(double f);

  // Which blocks (tile_blocks.h) were changed since the mask was last taken: what a region
  // delta sends of the tile. Over-approximate by contract: ScanIntegrator::Integrate marks
  // every block it may write (a marked block may be unchanged, never the reverse), and so do
  // ScaleCell, ClearCell and Scale; other edits (merges, clears, corrections) are reported as
  // whole tiles by their callers and need not mark. Not a statistic: copies start with none,
  // operator== ignores it.
  void MarkChanged(int x0, int y0, int x1, int y1) {
    AddTileBlocksOf(changed_blocks_, block_shift_, x0, y0, x1, y1);
  }
  void MarkCellChanged(int local) {
    const int x = local % size_, y = local / size_;
    MarkChanged(x, y, x, y);
  }
  TileBlocks TakeChangedBlocks() {
    const TileBlocks m = changed_blocks_;
    changed_blocks_ = {};
    return m;
  }

  // Multiplies every statistic of cell `local` by f: the mean and the disagreement stay, the
  // confidence scales (saturation and free-space evidence, docs/semantics.md).
  void ScaleCell(int local, double f) {
    assert(!is_packed());
    MarkCellChanged(local);
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
    assert(!is_packed());
    MarkCellChanged(local);
    w_[local] = s_[local] = q_[local] = 0.0;
    if (p_) {
      for (int m = 0; m < kPlaneMoments; ++m) p_[m * n() + local] = 0.0;
    }
    a_[local] = b_[local] = 0.0f;
  }

  // Ground kept aside (dynamics with transient_confirm_s > 0, docs/semantics.md "Transient
  // objects"): the statistics cell `local` had, seen traversable, when something appeared over
  // it, until the appearance is confirmed (then dropped) or expires (then restored). Sorted by
  // `local`, each cell once; empty in every map without the rule. Part of the tile's state:
  // copied, compared, scaled by Scale, stored (tile_codec.h); a merge keeps it only into an
  // empty tile (Add).
  struct PendingGround {
    int32_t local = 0;
    CellStats saved;
    int64_t appeared_ns = 0;   // the stamp of the scan that saw the appearance
    int64_t last_seen_ns = 0;  // the last scan that still saw it (semantics)
    bool operator==(const PendingGround& o) const;
  };
  std::vector<PendingGround>& pending() { return pending_; }
  const std::vector<PendingGround>& pending() const { return pending_; }

  static constexpr size_t kBytesPerCell = 3 * sizeof(double) + 2 * sizeof(float);
  static constexpr size_t kPlaneBytesPerCell = kPlaneMoments * sizeof(double);
  size_t bytes_per_cell() const { return kBytesPerCell + (plane_ ? kPlaneBytesPerCell : 0); }

 private:
  // The packed form: bit i of mask_ says whether cell i is stored; rank_[j] counts the stored
  // cells before word j; a stored cell's values sit at its rank r: pd_[r] (W), pd_[c + r] (S),
  // pd_[2c + r] (Q), pd_[(3 + m)c + r] (plane moment m), pf_[r] (A), pf_[c + r] (B), c being
  // packed_count_.
  static constexpr int kPackedDoubles = 3;
  template <typename T>
  T* DenseOnly(T* p) const {
    assert(!is_packed());
    return p;
  }
  size_t n() const { return static_cast<size_t>(size_) * size_; }
  size_t words() const { return (n() + 63) / 64; }
  void AllocateDense();
  void FreeDense();
  void FreePacked();
  // Builds the packed arrays from the dense arrays of `dense` (this tile or another of its size
  // and form); leaves this tile's dense arrays as they are.
  void PackFrom(const Tile& dense);
  struct NoArrays {};
  Tile(NoArrays, const Tile& like) : size_(like.size_), plane_(like.plane_) {}
  // The stored rank of cell `local`, or -1 when the packed tile does not store it.
  int PackedRank(int local) const {
    const uint64_t word = mask_[local >> 6];
    const uint64_t bit = uint64_t{1} << (local & 63);
    if ((word & bit) == 0) return -1;
    return static_cast<int>(rank_[local >> 6]) + std::popcount(word & (bit - 1));
  }
  CellStats PackedCellAt(int local) const;
  void PackedPlaneOf(int local, double* out) const;
  KnownCells PackedKnown() const;
  bool PackedEqual(const Tile& other) const;

  int size_;
  bool plane_;
  int block_shift_ = TileBlockShift(size_);
  TileBlocks changed_blocks_;
  uint64_t version_ = 0;
  std::vector<PendingGround> pending_;
  int64_t stamp_ns_ = 0;
  std::unique_ptr<double[]> w_, s_, q_;
  std::unique_ptr<float[]> a_, b_;
  std::unique_ptr<double[]> p_;  // kPlaneMoments arrays of n(), or null
  // Packed form (all null, count 0, while dense).
  int packed_count_ = 0;
  std::unique_ptr<uint64_t[]> mask_;
  std::unique_ptr<uint32_t[]> rank_;
  std::unique_ptr<double[]> pd_;
  std::unique_ptr<float[]> pf_;
};

}  // namespace bgkmap
