#include "bgkmap/core/tile.h"

#include <algorithm>
#include <cstring>

namespace bgkmap {
namespace {

template <typename T>
std::unique_ptr<T[]> CopyArray(const std::unique_ptr<T[]>& from, size_t count) {
  if (from == nullptr) return nullptr;
  std::unique_ptr<T[]> out(new T[count]);
  std::copy_n(from.get(), count, out.get());
  return out;
}

template <typename T>
bool SameBits(const T* a, const T* b, size_t count) {
  return count == 0 || std::memcmp(a, b, count * sizeof(T)) == 0;
}

uint64_t Bits(double v) { return std::bit_cast<uint64_t>(v); }
uint32_t Bits(float v) { return std::bit_cast<uint32_t>(v); }

}  // namespace

Tile::Tile(int tile_size, bool plane_moments) : size_(tile_size), plane_(plane_moments) {
  AllocateDense();
}

Tile::Tile(const Tile& o) : size_(o.size_), plane_(o.plane_) { Assign(o); }

void Tile::AllocateDense() {
  w_.reset(new double[n()]());
  s_.reset(new double[n()]());
  q_.reset(new double[n()]());
  a_.reset(new float[n()]());
  b_.reset(new float[n()]());
  if (plane_) p_.reset(new double[kPlaneMoments * n()]());
}

void Tile::FreeDense() {
  w_.reset();
  s_.reset();
  q_.reset();
  a_.reset();
  b_.reset();
  p_.reset();
}

void Tile::FreePacked() {
  packed_count_ = 0;
  mask_.reset();
  rank_.reset();
  pd_.reset();
  pf_.reset();
}

void Tile::Assign(const Tile& o) {
  if (this == &o) return;
  assert(size_ == o.size_);
  plane_ = o.plane_;
  version_ = o.version_;
  stamp_ns_ = o.stamp_ns_;
  pending_ = o.pending_;
  FreeDense();
  FreePacked();
  if (o.is_packed()) {
    const size_t c = static_cast<size_t>(o.packed_count_);
    packed_count_ = o.packed_count_;
    mask_ = CopyArray(o.mask_, words());
    rank_ = CopyArray(o.rank_, words());
    pd_ = CopyArray(o.pd_, c * (kPackedDoubles + (plane_ ? kPlaneMoments : 0)));
    pf_ = CopyArray(o.pf_, c * 2);
    return;
  }
  w_ = CopyArray(o.w_, n());
  s_ = CopyArray(o.s_, n());
  q_ = CopyArray(o.q_, n());
  a_ = CopyArray(o.a_, n());
  b_ = CopyArray(o.b_, n());
  p_ = CopyArray(o.p_, plane_ ? kPlaneMoments * n() : 0);
}

void Tile::Pack() {
  if (is_packed()) return;
  PackFrom(*this);
  FreeDense();
}

std::unique_ptr<Tile> Tile::PackedCopy(const Tile& o) {
  if (o.is_packed()) return std::make_unique<Tile>(o);
  std::unique_ptr<Tile> out(new Tile(NoArrays{}, o));
  out->version_ = o.version_;
  out->stamp_ns_ = o.stamp_ns_;
  out->pending_ = o.pending_;
  out->PackFrom(o);
  return out;
}

void Tile::PackFrom(const Tile& d) {
  const size_t N = n();
  mask_.reset(new uint64_t[words()]());
  rank_.reset(new uint32_t[words()]);
  int count = 0;
  for (size_t i = 0; i < N; ++i) {
    // Stored iff any bit of any statistic is set: -0.0 and denormals survive the round trip.
    uint64_t any = Bits(d.w_[i]) | Bits(d.s_[i]) | Bits(d.q_[i]) | Bits(d.a_[i]) | Bits(d.b_[i]);
    for (int m = 0; plane_ && m < kPlaneMoments; ++m) any |= Bits(d.p_[m * N + i]);
    if (any == 0) continue;
    mask_[i >> 6] |= uint64_t{1} << (i & 63);
    ++count;
  }
  uint32_t before = 0;
  for (size_t j = 0; j < words(); ++j) {
    rank_[j] = before;
    before += static_cast<uint32_t>(std::popcount(mask_[j]));
  }
  const size_t c = static_cast<size_t>(count);
  const int doubles = kPackedDoubles + (plane_ ? kPlaneMoments : 0);
  if (c > 0) {
    pd_.reset(new double[c * doubles]);
    pf_.reset(new float[c * 2]);
  }
  size_t r = 0;
  for (size_t i = 0; i < N && r < c; ++i) {
    if ((mask_[i >> 6] >> (i & 63) & 1) == 0) continue;
    pd_[r] = d.w_[i];
    pd_[c + r] = d.s_[i];
    pd_[2 * c + r] = d.q_[i];
    for (int m = 0; plane_ && m < kPlaneMoments; ++m)
      pd_[(kPackedDoubles + m) * c + r] = d.p_[m * N + i];
    pf_[r] = d.a_[i];
    pf_[c + r] = d.b_[i];
    ++r;
  }
  packed_count_ = count;
}

void Tile::Unpack() {
  if (!is_packed()) return;
  AllocateDense();
  const size_t N = n();
  const size_t c = static_cast<size_t>(packed_count_);
  size_t r = 0;
  for (size_t j = 0; j < words() && r < c; ++j) {
    for (uint64_t word = mask_[j]; word != 0; word &= word - 1) {
      const size_t i = j * 64 + static_cast<size_t>(std::countr_zero(word));
      w_[i] = pd_[r];
      s_[i] = pd_[c + r];
      q_[i] = pd_[2 * c + r];
      for (int m = 0; plane_ && m < kPlaneMoments; ++m)
        p_[m * N + i] = pd_[(kPackedDoubles + m) * c + r];
      a_[i] = pf_[r];
      b_[i] = pf_[c + r];
      ++r;
    }
  }
  FreePacked();
}

size_t Tile::MemoryBytes() const {
  const size_t kept = pending_.capacity() * sizeof(PendingGround);
  if (!is_packed()) return sizeof(Tile) + n() * bytes_per_cell() + kept;
  return sizeof(Tile) + words() * (sizeof(uint64_t) + sizeof(uint32_t)) +
         static_cast<size_t>(packed_count_) * bytes_per_cell() + kept;
}

Tile::CellStats Tile::PackedCellAt(int local) const {
  const int r = PackedRank(local);
  if (r < 0) return {};
  const size_t c = static_cast<size_t>(packed_count_);
  return {pd_[r], pd_[c + r], pd_[2 * c + r], pf_[r], pf_[c + r]};
}

void Tile::PackedPlaneOf(int local, double* out) const {
  const int r = PackedRank(local);
  const size_t c = static_cast<size_t>(packed_count_);
  for (int m = 0; m < kPlaneMoments; ++m) out[m] = r < 0 ? 0.0 : pd_[(kPackedDoubles + m) * c + r];
}

Tile::KnownCells Tile::PackedKnown() const {
  KnownCells out;
  const size_t c = static_cast<size_t>(packed_count_);
  size_t r = 0;
  for (size_t j = 0; j < words() && r < c; ++j) {
    for (uint64_t word = mask_[j]; word != 0; word &= word - 1, ++r) {
      if (!(pd_[r] > 0.0 || (pf_[r] + pf_[c + r]) > 0.0f)) continue;
      const int i = static_cast<int>(j * 64) + std::countr_zero(word);
      ++out.count;
      out.local_box.Extend({i % size_, i / size_});
    }
  }
  return out;
}

Tile::KnownCells Tile::Known() const {
  if (is_packed()) return PackedKnown();
  KnownCells out;
  const double* w = w_.get();
  const float* a = a_.get();
  const float* b = b_.get();
  for (int y = 0; y < size_; ++y) {
    const int row = y * size_;
    // Branch-free count first; the row's ends are looked for only in rows that have any.
    int in_row = 0;
    for (int x = 0; x < size_; ++x) {
      const int i = row + x;
      in_row += static_cast<int>((w[i] > 0.0) | ((a[i] + b[i]) > 0.0f));
    }
    if (in_row == 0) continue;
    out.count += in_row;
    int first = 0, last = size_ - 1;
    while (!IsKnown(row + first)) ++first;
    while (!IsKnown(row + last)) --last;
    out.local_box.Extend({first, y});
    out.local_box.Extend({last, y});
  }
  return out;
}

void Tile::Add(const Tile& o) {
  assert(!is_packed());
  if (o.is_packed()) {
    // Every cell, the unstored ones too: +0 + -0 is +0, as in the dense sum.
    Tile dense(o);
    dense.Unpack();
    return Add(dense);
  }
  // Ground kept aside is kept only by a merge into an empty tile (a map loaded or imported into
  // nothing): it was kept from one map's own cells, which the sum changes. Either order of a
  // merge drops it alike.
  if (pending_.empty() && Empty()) {
    pending_ = o.pending_;
  } else {
    pending_.clear();
  }
  for (size_t i = 0; i < n(); ++i) {
    w_[i] += o.w_[i];
    s_[i] += o.s_[i];
    q_[i] += o.q_[i];
    a_[i] += o.a_[i];
    b_[i] += o.b_[i];
  }
  // Maps merge only with equal parameters, so both keep plane moments or neither does.
  if (p_ && o.p_) {
    for (size_t i = 0; i < kPlaneMoments * n(); ++i) p_[i] += o.p_[i];
  }
}

void Tile::Scale(double f) {
  assert(!is_packed());
  changed_blocks_ = TileBlocks::All();
  for (size_t i = 0; i < n(); ++i) {
    w_[i] *= f;
    s_[i] *= f;
    q_[i] *= f;
  }
  if (p_) {
    for (size_t i = 0; i < kPlaneMoments * n(); ++i) p_[i] *= f;
  }
  // The Beta counts in double, as ScaleCell: a product rounded once to float.
  for (size_t i = 0; i < n(); ++i) {
    a_[i] = static_cast<float>(a_[i] * f);
    b_[i] = static_cast<float>(b_[i] * f);
  }
  // Ground kept aside is as of the tile's stamp too.
  for (PendingGround& p : pending_) {
    p.saved.w *= f;
    p.saved.s *= f;
    p.saved.q *= f;
    p.saved.a = static_cast<float>(p.saved.a * f);
    p.saved.b = static_cast<float>(p.saved.b * f);
  }
}

void Tile::Clear() {
  pending_.clear();
  if (is_packed()) {
    FreePacked();
    AllocateDense();  // zeroed
    return;
  }
  std::fill_n(w_.get(), n(), 0.0);
  std::fill_n(s_.get(), n(), 0.0);
  std::fill_n(q_.get(), n(), 0.0);
  std::fill_n(a_.get(), n(), 0.0f);
  std::fill_n(b_.get(), n(), 0.0f);
  if (p_) std::fill_n(p_.get(), kPlaneMoments * n(), 0.0);
}

bool Tile::PackedEqual(const Tile& o) const {
  const size_t c = static_cast<size_t>(packed_count_);
  return packed_count_ == o.packed_count_ && SameBits(mask_.get(), o.mask_.get(), words()) &&
         SameBits(pd_.get(), o.pd_.get(), c * (kPackedDoubles + (plane_ ? kPlaneMoments : 0))) &&
         SameBits(pf_.get(), o.pf_.get(), c * 2);
}

bool Tile::operator==(const Tile& o) const {
  // Bitwise comparison: "identical maps" means identical statistics, not merely close ones.
  if (size_ != o.size_ || stamp_ns_ != o.stamp_ns_ || has_plane() != o.has_plane() ||
      pending_ != o.pending_) {
    return false;
  }
  // Packing is a function of the statistics, so two packed tiles compare in that form.
  if (is_packed() && o.is_packed()) return PackedEqual(o);
  if (is_packed() || o.is_packed()) {
    Tile a(*this), b(o);
    a.Unpack();
    b.Unpack();
    return a == b;
  }
  return SameBits(w_.get(), o.w_.get(), n()) && SameBits(s_.get(), o.s_.get(), n()) &&
         SameBits(q_.get(), o.q_.get(), n()) && SameBits(a_.get(), o.a_.get(), n()) &&
         SameBits(b_.get(), o.b_.get(), n()) &&
         (!p_ || SameBits(p_.get(), o.p_.get(), kPlaneMoments * n()));
}

bool Tile::PendingGround::operator==(const PendingGround& o) const {
  return local == o.local && appeared_ns == o.appeared_ns && last_seen_ns == o.last_seen_ns &&
         SameBits(&saved.w, &o.saved.w, 1) && SameBits(&saved.s, &o.saved.s, 1) &&
         SameBits(&saved.q, &o.saved.q, 1) && SameBits(&saved.a, &o.saved.a, 1) &&
         SameBits(&saved.b, &o.saved.b, 1);
}

}  // namespace bgkmap
