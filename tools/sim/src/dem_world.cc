#include "bgkmap/sim/dem_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace bgkmap::sim {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Distance from (x, y) to the segment (x0, y0)-(x1, y1).
double SegmentDistance(double x, double y, const Ditch& d) {
  const double vx = d.x1 - d.x0, vy = d.y1 - d.y0;
  const double len2 = vx * vx + vy * vy;
  double t = len2 > 0 ? ((x - d.x0) * vx + (y - d.y0) * vy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double px = d.x0 + t * vx - x, py = d.y0 + t * vy - y;
  return std::sqrt(px * px + py * py);
}

// floor(v) as an index, clamped to [-1, limit] so far-away coordinates cannot overflow.
int64_t FloorIndex(double v, int64_t limit) {
  if (!(v > -1.0)) return -1;
  return std::min(static_cast<int64_t>(std::floor(v)), limit);
}

}  // namespace

int64_t FillNoData(HeightGrid& g) {
  int64_t filled = 0;
  std::vector<float> next = g.values;
  for (bool changed = true; changed;) {
    changed = false;
    for (int64_t r = 0; r < g.rows; ++r) {
      for (int64_t c = 0; c < g.cols; ++c) {
        if (!std::isnan(g.values[static_cast<size_t>(r * g.cols + c)])) continue;
        double sum = 0;
        int n = 0;
        for (int64_t dr = -1; dr <= 1; ++dr) {
          for (int64_t dc = -1; dc <= 1; ++dc) {
            const int64_t rr = r + dr, cc = c + dc;
            if (rr < 0 || cc < 0 || rr >= g.rows || cc >= g.cols) continue;
            const float v = g.values[static_cast<size_t>(rr * g.cols + cc)];
            if (!std::isnan(v)) sum += v, ++n;
          }
        }
        if (n == 0) continue;
        next[static_cast<size_t>(r * g.cols + c)] = static_cast<float>(sum / n);
        ++filled;
        changed = true;
      }
    }
    g.values = next;
  }
  return filled;
}

DemWorld::DemWorld(HeightGrid grid, const ObstacleOptions& o) : grid_(std::move(grid)) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> ux(o.xmin, o.xmax), uy(o.ymin, o.ymax), u01(0.0, 1.0);
  for (int i = 0; i < o.rocks; ++i) {
    rocks_.push_back({ux(rng), uy(rng), 0.3 + 0.9 * u01(rng), 0.25 + 0.75 * u01(rng)});
  }
  for (int i = 0; i < o.ditches; ++i) {
    const double x = ux(rng), y = uy(rng), len = 15.0 + 25.0 * u01(rng);
    const double a = 2.0 * 3.141592653589793 * u01(rng);
    ditches_.push_back({x, y, x + len * std::cos(a), y + len * std::sin(a), 0.8 + 0.8 * u01(rng),
                        0.3 + 0.4 * u01(rng)});
  }
  max_height_ = -std::numeric_limits<double>::infinity();
  for (float v : grid_.values) {
    if (!std::isnan(v)) max_height_ = std::max(max_height_, static_cast<double>(v));
  }
  max_height_ += 2.0;  // rocks are at most 1 m tall
  BuildBound();
  bx0_ = o.xmin - kBucket;
  by0_ = o.ymin - kBucket;
  bcols_ = static_cast<int64_t>((o.xmax - o.xmin) / kBucket) + 3;
  brows_ = static_cast<int64_t>((o.ymax - o.ymin) / kBucket) + 3;
  buckets_.resize(static_cast<size_t>(bcols_ * brows_));
  for (int i = 0; i < static_cast<int>(rocks_.size()); ++i) {
    const Rock& r = rocks_[i];
    const int64_t c0 = static_cast<int64_t>((r.x - r.radius - bx0_) / kBucket);
    const int64_t c1 = static_cast<int64_t>((r.x + r.radius - bx0_) / kBucket);
    const int64_t r0 = static_cast<int64_t>((r.y - r.radius - by0_) / kBucket);
    const int64_t r1 = static_cast<int64_t>((r.y + r.radius - by0_) / kBucket);
    for (int64_t br = std::max<int64_t>(r0, 0); br <= std::min(r1, brows_ - 1); ++br) {
      for (int64_t bc = std::max<int64_t>(c0, 0); bc <= std::min(c1, bcols_ - 1); ++bc) {
        buckets_[static_cast<size_t>(br * bcols_ + bc)].push_back(i);
      }
    }
  }
}

void DemWorld::BuildBound() {
  const int64_t sc = grid_.cols - 1, sr = grid_.rows - 1;  // interpolation squares
  if (sc <= 0 || sr <= 0) return;
  const double cs = grid_.cellsize, ytop = grid_.y0 + grid_.rows * cs;
  std::vector<float> rock(static_cast<size_t>(sc * sr), 0.0f);
  for (const Rock& r : rocks_) {
    const int64_t c0 = std::max<int64_t>(FloorIndex((r.x - r.radius - grid_.x0) / cs - 0.5, sc), 0);
    const int64_t c1 = std::min(FloorIndex((r.x + r.radius - grid_.x0) / cs - 0.5, sc), sc - 1);
    const int64_t r0 = std::max<int64_t>(FloorIndex((ytop - r.y - r.radius) / cs - 0.5, sr), 0);
    const int64_t r1 = std::min(FloorIndex((ytop - r.y + r.radius) / cs - 0.5, sr), sr - 1);
    for (int64_t j = r0; j <= r1; ++j) {
      for (int64_t i = c0; i <= c1; ++i) {
        float& m = rock[static_cast<size_t>(j * sc + i)];
        m = std::max(m, static_cast<float>(r.height));
      }
    }
  }
  std::vector<float> bound(rock.size());
  for (int64_t j = 0; j < sr; ++j) {
    for (int64_t i = 0; i < sc; ++i) {
      const size_t k = static_cast<size_t>(j * grid_.cols + i);
      const float a = grid_.values[k], b = grid_.values[k + 1];
      const float c = grid_.values[k + grid_.cols], d = grid_.values[k + grid_.cols + 1];
      const size_t s = static_cast<size_t>(j * sc + i);
      if (std::isnan(a) || std::isnan(b) || std::isnan(c) || std::isnan(d)) {
        bound[s] = -std::numeric_limits<float>::infinity();  // SurfaceHeight is NaN here
      } else {
        // 1 mm above the exact bound absorbs the rounding of the bilinear weights.
        bound[s] = std::max({a, b, c, d}) + rock[s] + 1e-3f;
      }
    }
  }
  bound_ = MaxMipmap(sc, sr, std::move(bound));
}

double DemWorld::MaxHeightIn(double x0, double y0, double x1, double y1) const {
  const double cs = grid_.cellsize, ytop = grid_.y0 + grid_.rows * cs;
  const int64_t sc = bound_.cols(), sr = bound_.rows();
  return bound_.Max(
      FloorIndex((x0 - grid_.x0) / cs - 0.5, sc), FloorIndex((ytop - y1) / cs - 0.5, sr),
      FloorIndex((x1 - grid_.x0) / cs - 0.5, sc), FloorIndex((ytop - y0) / cs - 0.5, sr));
}

double DemWorld::TerrainHeight(double x, double y) const {
  // Bilinear between cell centres.
  const double fc = (x - grid_.x0) / grid_.cellsize - 0.5;
  const double fr = (grid_.y0 + grid_.rows * grid_.cellsize - y) / grid_.cellsize - 0.5;
  const double c0 = std::floor(fc), r0 = std::floor(fr);
  if (!(c0 >= 0 && r0 >= 0 && c0 + 1 < grid_.cols && r0 + 1 < grid_.rows)) return kNaN;
  const size_t i = static_cast<size_t>(r0) * grid_.cols + static_cast<size_t>(c0);
  const double a = grid_.values[i], b = grid_.values[i + 1];
  const double c = grid_.values[i + grid_.cols], d = grid_.values[i + grid_.cols + 1];
  const double tx = fc - c0, ty = fr - r0;
  return (a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty;  // NaN propagates
}

double DemWorld::SurfaceHeight(double x, double y) const {
  double z = TerrainHeight(x, y);
  if (std::isnan(z)) return z;
  for (const Ditch& d : ditches_) {
    const double u = SegmentDistance(x, y, d) / (0.5 * d.width);
    if (u < 1.0) z -= d.depth * (1.0 - u * u);
  }
  const int64_t bc = static_cast<int64_t>(std::floor((x - bx0_) / kBucket));
  const int64_t br = static_cast<int64_t>(std::floor((y - by0_) / kBucket));
  if (bc < 0 || br < 0 || bc >= bcols_ || br >= brows_) return z;
  double bump = 0.0;
  for (int i : buckets_[static_cast<size_t>(br * bcols_ + bc)]) {
    const Rock& r = rocks_[i];
    const double u2 = ((x - r.x) * (x - r.x) + (y - r.y) * (y - r.y)) / (r.radius * r.radius);
    if (u2 < 1.0) bump = std::max(bump, r.height * std::sqrt(1.0 - u2));
  }
  return z + bump;
}

}  // namespace bgkmap::sim
