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
  KernelStencil(double resolution, double kernel_length);

  int radius() const { return radius_; }  // largest |dy| (and |dx|) with nonzero weight
  int row_count() const { return 2 * radius_ + 1; }
  // Row r corresponds to dy = r - radius().
  int half_width(int row) const { return half_width_[row]; }
  // Weights of row r for dx = -half_width .. +half_width.
  const float* row_weights(int row) const { return weights_.data() + row_offset_[row]; }
  const double* row_weights_double(int row) const { return weights_d_.data() + row_offset_[row]; }
  int cell_count() const { return static_cast<int>(weights_.size()); }

 private:
  int radius_ = 0;
  std::vector<int> half_width_;
  std::vector<int> row_offset_;
  std::vector<float> weights_;
  std::vector<double> weights_d_;
};

}  // namespace bgkmap
