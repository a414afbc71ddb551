#include "bgkmap/core/sparse_kernel.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace bgkmap {

double SparseKernel(double d, double l) {
  if (d >= l || d < 0) return d < 0 ? SparseKernel(-d, l) : 0.0;
  const double r = d / l;
  const double two_pi_r = 2.0 * std::numbers::pi * r;
  return ((2.0 + std::cos(two_pi_r)) / 3.0) * (1.0 - r) +
         std::sin(two_pi_r) / (2.0 * std::numbers::pi);
}

KernelStencil::KernelStencil(double resolution, double kernel_length, double centre_weight) {
  // Largest integer offset whose distance can still be < l.
  radius_ = static_cast<int>(std::ceil(kernel_length / resolution));
  half_width_.assign(2 * radius_ + 1, -1);
  row_offset_.assign(2 * radius_ + 1, 0);
  for (int dy = -radius_; dy <= radius_; ++dy) {
    const int row = dy + radius_;
    row_offset_[row] = static_cast<int>(weights_.size());
    int hw = -1;
    for (int dx = 0; dx <= radius_; ++dx) {
      if (resolution * std::hypot(dx, dy) < kernel_length) hw = dx;  // semantics: d < l
    }
    half_width_[row] = hw;
    for (int dx = -hw; dx <= hw; ++dx) {
      // k -> 0 like (1 - d/l)^4 at the support's edge; clamp rounding below zero.
      const double k =
          dx == 0 && dy == 0
              ? centre_weight
              : std::max(0.0, SparseKernel(resolution * std::hypot(dx, dy), kernel_length));
      weights_d_.push_back(k);
      weights_.push_back(static_cast<float>(k));
      const double u = -dx * resolution, v = -dy * resolution;
      moments_u_.push_back(u);
      moments_v_.push_back(v);
      const double m[kGeometricMoments] = {k * u, k * v, k * u * u, k * u * v, k * v * v};
      for (int i = 0; i < kGeometricMoments; ++i) moments_[i].push_back(m[i]);
    }
  }
  // Trim empty outer rows so radius() is the true reach.
  while (radius_ > 0 && half_width_.front() < 0 && half_width_.back() < 0) {
    half_width_.erase(half_width_.begin());
    half_width_.pop_back();
    row_offset_.erase(row_offset_.begin());
    row_offset_.pop_back();
    --radius_;
  }
}

double KernelStencil::total_weight() const {
  double sum = 0.0;
  for (double k : weights_d_) sum += k;
  return sum;
}

}  // namespace bgkmap
