#include "bgkmap/sim/max_mipmap.h"

#include <algorithm>
#include <limits>

namespace bgkmap::sim {
namespace {
constexpr float kNone = -std::numeric_limits<float>::infinity();
}  // namespace

MaxMipmap::MaxMipmap(int64_t cols, int64_t rows, std::vector<float> values) {
  if (cols <= 0 || rows <= 0 || values.size() != static_cast<size_t>(cols * rows)) return;
  cols_.push_back(cols);
  rows_.push_back(rows);
  levels_.push_back(std::move(values));
  while (cols_.back() > 1 || rows_.back() > 1) {
    const int64_t pc = cols_.back(), pr = rows_.back();
    const int64_t nc = (pc + 1) / 2, nr = (pr + 1) / 2;
    std::vector<float> next(static_cast<size_t>(nc * nr), kNone);
    const std::vector<float>& prev = levels_.back();
    for (int64_t r = 0; r < pr; ++r) {
      for (int64_t c = 0; c < pc; ++c) {
        float& m = next[static_cast<size_t>((r / 2) * nc + c / 2)];
        m = std::max(m, prev[static_cast<size_t>(r * pc + c)]);
      }
    }
    cols_.push_back(nc);
    rows_.push_back(nr);
    levels_.push_back(std::move(next));
  }
}

float MaxMipmap::Max(int64_t c0, int64_t r0, int64_t c1, int64_t r1) const {
  if (levels_.empty()) return kNone;
  if (c0 > c1) std::swap(c0, c1);
  if (r0 > r1) std::swap(r0, r1);
  c0 = std::max<int64_t>(c0, 0);
  r0 = std::max<int64_t>(r0, 0);
  c1 = std::min(c1, cols_[0] - 1);
  r1 = std::min(r1, rows_[0] - 1);
  if (c0 > c1 || r0 > r1) return kNone;
  // The finest level where the rectangle spans at most 2 x 2 cells.
  size_t k = 0;
  while (((c1 >> k) - (c0 >> k) > 1 || (r1 >> k) - (r0 >> k) > 1) && k + 1 < levels_.size()) ++k;
  c0 >>= k, c1 >>= k, r0 >>= k, r1 >>= k;
  const std::vector<float>& v = levels_[k];
  float m = kNone;
  for (int64_t r = r0; r <= r1; ++r) {
    for (int64_t c = c0; c <= c1; ++c) m = std::max(m, v[static_cast<size_t>(r * cols_[k] + c)]);
  }
  return m;
}

}  // namespace bgkmap::sim
