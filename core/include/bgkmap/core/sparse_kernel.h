// The sparse kernel of Melkumyan and Ramos (paper Eq. 7) and its precomputed integer stencil.
#pragma once

#include <vector>

namespace bgkmap {

// k(d) = ((2 + cos(2 pi d/l)) / 3) (1 - d/l) + sin(2 pi d/l) / (2 pi) for d < l, else 0.
// k(0) = 1, k decreases monotonically to k(l) = 0 with zero slope there.
double SparseKernel(double d, double l);

// Training locations are cell centres, so between two cells the kernel depends only on the
// integer offset. The stencil lists every offset with d < l as rows of contiguous cells:
// row dy spans dx in [-half_width[dy], +half_width[dy]] (a disk is convex), which lets the
// integrator update a row with one vectorisable loop.
class KernelStencil {
 public:
  // `centre_weight` replaces k(0) = 1 at the zero offset (bgk-ll: a cell's own observation
  // weighs as much as its whole neighbourhood, docs/semantics.md "bgk-ll").
  KernelStencil(double resolution, double kernel_length, double centre_weight = 1.0);

  int radius() const { return radius_; }  // largest |dy| (and |dx|) with nonzero weight
  int row_count() const { return 2 * radius_ + 1; }
  // Row r corresponds to dy = r - radius().
  int half_width(int row) const { return half_width_[row]; }
  // Weights of row r for dx = -half_width .. +half_width.
  const float* row_weights(int row) const { return weights_.data() + row_offset_[row]; }
  const double* row_weights_double(int row) const { return weights_d_.data() + row_offset_[row]; }
  int cell_count() const { return static_cast<int>(weights_.size()); }
  // The sum of the weights: what one cell gains when every cell within l is observed once.
  double total_weight() const;

  // Local-linear moments of the stencil (bgk-ll). For the target cell at offset (dx, dy) from a
  // training cell, the training cell lies at (u, v) = (-dx, -dy) * resolution metres from it;
  // moment m of an entry is k*u, k*v, k*u*u, k*u*v, k*v*v (m = 0..4), laid out as the weights.
  // `at` is a pointer into row_weights_double(), as handed to a run of cells.
  static constexpr int kGeometricMoments = 5;
  const double* moments_at(int m, const double* at) const {
    return moments_[m].data() + (at - weights_d_.data());
  }
  // u and v of the entry `at` points to, metres.
  double u_at(const double* at) const { return moments_u_[at - weights_d_.data()]; }
  double v_at(const double* at) const { return moments_v_[at - weights_d_.data()]; }

 private:
  int radius_ = 0;
  std::vector<int> half_width_;
  std::vector<int> row_offset_;
  std::vector<float> weights_;
  std::vector<double> weights_d_;
  std::vector<double> moments_[kGeometricMoments];
  std::vector<double> moments_u_, moments_v_;
};

}  // namespace bgkmap
