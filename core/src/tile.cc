#include "bgkmap/core/tile.h"

#include <algorithm>
#include <cstring>

namespace bgkmap {

Tile::Tile(int tile_size)
    : size_(tile_size),
      w_(new double[n()]()),
      s_(new double[n()]()),
      a_(new float[n()]()),
      b_(new float[n()]()) {}

Tile::Tile(const Tile& o) : Tile(o.size_) {
  version_ = o.version_;
  std::copy_n(o.w_.get(), n(), w_.get());
  std::copy_n(o.s_.get(), n(), s_.get());
  std::copy_n(o.a_.get(), n(), a_.get());
  std::copy_n(o.b_.get(), n(), b_.get());
}

int Tile::CountKnown() const {
  int known = 0;
  for (int i = 0; i < cell_count(); ++i) known += IsKnown(i) ? 1 : 0;
  return known;
}

CellBox Tile::KnownLocalBox() const {
  CellBox box;
  for (int i = 0; i < cell_count(); ++i) {
    if (IsKnown(i)) box.Extend({i % size_, i / size_});
  }
  return box;
}

void Tile::Add(const Tile& o) {
  for (size_t i = 0; i < n(); ++i) {
    w_[i] += o.w_[i];
    s_[i] += o.s_[i];
    a_[i] += o.a_[i];
    b_[i] += o.b_[i];
  }
}

void Tile::Clear() {
  std::fill_n(w_.get(), n(), 0.0);
  std::fill_n(s_.get(), n(), 0.0);
  std::fill_n(a_.get(), n(), 0.0f);
  std::fill_n(b_.get(), n(), 0.0f);
}

bool Tile::operator==(const Tile& o) const {
  // Bitwise comparison: "identical maps" means identical statistics, not merely close ones.
  return size_ == o.size_ && std::memcmp(w_.get(), o.w_.get(), n() * sizeof(double)) == 0 &&
         std::memcmp(s_.get(), o.s_.get(), n() * sizeof(double)) == 0 &&
         std::memcmp(a_.get(), o.a_.get(), n() * sizeof(float)) == 0 &&
         std::memcmp(b_.get(), o.b_.get(), n() * sizeof(float)) == 0;
}

}  // namespace bgkmap
