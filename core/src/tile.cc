#include "bgkmap/core/tile.h"

#include <algorithm>
#include <cstring>

namespace bgkmap {

Tile::Tile(int tile_size, bool plane_moments)
    : size_(tile_size),
      w_(new double[n()]()),
      s_(new double[n()]()),
      q_(new double[n()]()),
      a_(new float[n()]()),
      b_(new float[n()]()),
      p_(plane_moments ? new double[kPlaneMoments * n()]() : nullptr) {}

Tile::Tile(const Tile& o) : Tile(o.size_, o.has_plane()) {
  if (p_) std::copy_n(o.p_.get(), kPlaneMoments * n(), p_.get());
  version_ = o.version_;
  stamp_ns_ = o.stamp_ns_;
  std::copy_n(o.w_.get(), n(), w_.get());
  std::copy_n(o.s_.get(), n(), s_.get());
  std::copy_n(o.q_.get(), n(), q_.get());
  std::copy_n(o.a_.get(), n(), a_.get());
  std::copy_n(o.b_.get(), n(), b_.get());
}

Tile::KnownCells Tile::Known() const {
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
}

void Tile::Clear() {
  std::fill_n(w_.get(), n(), 0.0);
  std::fill_n(s_.get(), n(), 0.0);
  std::fill_n(q_.get(), n(), 0.0);
  std::fill_n(a_.get(), n(), 0.0f);
  std::fill_n(b_.get(), n(), 0.0f);
  if (p_) std::fill_n(p_.get(), kPlaneMoments * n(), 0.0);
}

bool Tile::operator==(const Tile& o) const {
  // Bitwise comparison: "identical maps" means identical statistics, not merely close ones.
  return size_ == o.size_ && stamp_ns_ == o.stamp_ns_ &&
         std::memcmp(w_.get(), o.w_.get(), n() * sizeof(double)) == 0 &&
         std::memcmp(s_.get(), o.s_.get(), n() * sizeof(double)) == 0 &&
         std::memcmp(q_.get(), o.q_.get(), n() * sizeof(double)) == 0 &&
         std::memcmp(a_.get(), o.a_.get(), n() * sizeof(float)) == 0 &&
         std::memcmp(b_.get(), o.b_.get(), n() * sizeof(float)) == 0 &&
         has_plane() == o.has_plane() &&
         (!p_ || std::memcmp(p_.get(), o.p_.get(), kPlaneMoments * n() * sizeof(double)) == 0);
}

}  // namespace bgkmap
