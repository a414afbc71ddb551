#include "bgkmap/core/band_cut.h"

#include <algorithm>
#include <limits>

namespace bgkmap {
namespace {

// Cells with a coordinate in [a, b), from the running sums (sums[i]: cells before first + i).
class CellCounter {
 public:
  CellCounter(const std::vector<int64_t>& cells, int64_t first) : first_(first) {
    sums_.resize(cells.size() + 1, 0);
    for (size_t i = 0; i < cells.size(); ++i) sums_[i + 1] = sums_[i] + cells[i];
  }
  int64_t Between(int64_t a, int64_t b) const { return Before(b) - Before(a); }
  int64_t total() const { return sums_.back(); }

 private:
  int64_t Before(int64_t v) const {
    const int64_t i = std::clamp<int64_t>(v - first_, 0, static_cast<int64_t>(sums_.size()) - 1);
    return sums_[static_cast<size_t>(i)];
  }
  int64_t first_;
  std::vector<int64_t> sums_;
};

constexpr int64_t kLow = std::numeric_limits<int64_t>::min() / 4;
constexpr int64_t kHigh = std::numeric_limits<int64_t>::max() / 4;

// The fewest bands whose work is each at most `cap`, each reaching as far as it can (the work of
// a band grows with its extent, so going farthest first never needs more bands); empty if the
// cut needs more than `bands`.
std::vector<int64_t> GreedyCut(const CellCounter& count, const std::vector<int64_t>& candidates,
                               int halo, int bands, int64_t cap, bool* fits) {
  std::vector<int64_t> borders;
  int64_t lo = kLow;
  size_t next = 0;  // the first candidate above lo
  while (count.Between(lo - halo, kHigh) > cap) {
    size_t reach = next;
    while (reach < candidates.size() && count.Between(lo - halo, candidates[reach] + halo) <= cap) {
      ++reach;
    }
    if (reach == next || static_cast<int>(borders.size()) + 1 >= bands) {
      *fits = false;
      return {};
    }
    lo = candidates[reach - 1];
    borders.push_back(lo);
    next = reach;
  }
  *fits = true;
  return borders;
}

}  // namespace

std::vector<int64_t> CutBorders(const std::vector<int64_t>& cells, int64_t first, int tile_size,
                                int halo, int bands) {
  if (bands <= 1 || cells.empty() || tile_size <= 0) return {};
  const CellCounter count(cells, first);
  std::vector<int64_t> candidates;
  const int64_t end = first + static_cast<int64_t>(cells.size());
  // The tile border at or below `first` (floor division, for negative coordinates too); the
  // candidates are the borders above it, inside the cells' extent.
  int64_t t =
      (first >= 0 ? first / tile_size : -((-first + tile_size - 1) / tile_size)) * tile_size;
  for (t += tile_size; t < end; t += tile_size) candidates.push_back(t);
  // The least cap that fits, by bisection: one band (cap = every cell) always fits.
  int64_t lo = 0, hi = count.total();
  while (lo < hi) {
    const int64_t mid = lo + (hi - lo) / 2;
    bool fits = false;
    GreedyCut(count, candidates, halo, bands, mid, &fits);
    if (fits) {
      hi = mid;
    } else {
      lo = mid + 1;
    }
  }
  bool fits = false;
  return GreedyCut(count, candidates, halo, bands, hi, &fits);
}

CellBox TileBand::Reach(int halo) const {
  constexpr int kLow = std::numeric_limits<int>::min(), kHigh = std::numeric_limits<int>::max();
  const int a = static_cast<int>(std::max<int64_t>(kLow, lo - halo));
  const int b = static_cast<int>(std::min<int64_t>(kHigh, hi - 1 + halo));
  return along_x ? CellBox{{a, kLow}, {b, kHigh}} : CellBox{{kLow, a}, {kHigh, b}};
}

std::vector<TileBand> BandsBetween(const std::vector<int64_t>& borders, bool along_x) {
  std::vector<TileBand> bands;
  TileBand band;
  band.along_x = along_x;
  for (const int64_t border : borders) {
    band.hi = border;
    bands.push_back(band);
    band.lo = border;
  }
  band.hi = TileBand{}.hi;
  bands.push_back(band);
  return bands;
}

}  // namespace bgkmap
