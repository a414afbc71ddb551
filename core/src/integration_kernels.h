// The inner loops of scan integration: adding one observation to a run of cells' sufficient
// statistics, and the confidence caps (docs/semantics.md 4, 7, "Dynamics"). Each is the one place
// its arithmetic is written, so every method, dynamics and forgetting mode sums in the same order.
#pragma once

#include <cmath>
#include <limits>

#include "bgkmap/core/sparse_kernel.h"
#include "bgkmap/core/tile.h"

namespace bgkmap::internal {

// Adds observation y (yy = y * y) to a run of kernel weights k: W += k g, S += k g y and, with the
// second moment (dynamics), Q += k g yy. Without a gain the product k g is k itself, so forgetting
// off sums bitwise as if no gain existed.
template <bool kSecondMoment, bool kGain>
inline void AddElevationRun(double* __restrict w, double* __restrict s, double* __restrict q,
                            const double* k, int len, double g, double y, double yy) {
  for (int j = 0; j < len; ++j) {
    const double kg = kGain ? k[j] * g : k[j];
    w[j] += kg;
    s[j] += kg * y;
    if constexpr (kSecondMoment) q[j] += kg * yy;
  }
}

// Adds training value v (va = v, vb = 1 - v) to a run of Beta pseudo-counts with weights k.
template <bool kGain>
inline void AddBetaRun(float* __restrict a, float* __restrict b, const float* k, int len, float g,
                       float va, float vb) {
  for (int j = 0; j < len; ++j) {
    const float kg = kGain ? k[j] * g : k[j];
    a[j] += kg * va;
    b[j] += kg * vb;
  }
}

// Scales the cells of [w, w + len) whose elevation weight passed `cap` back onto it.
inline void CapElevation(double* w, double* s, double* q, int len, double cap) {
  for (int j = 0; j < len; ++j) {
    if (w[j] > cap) {
      const double f = cap / w[j];
      w[j] = cap;
      s[j] *= f;
      q[j] *= f;
    }
  }
}

// The mean of cell i's own observations in a bgk-ll tile, NaN if it has none (a ratio: a read
// factor would cancel).
inline double OwnHeight(const Tile& tile, int i) {
  const double own_w = tile.plane(Tile::kOwnW)[i];
  return own_w > 0.0 ? tile.plane(Tile::kOwnS)[i] / own_w
                     : std::numeric_limits<double>::quiet_NaN();
}

// CapElevation for a tile with plane moments: the cell's moments scale with its weight.
inline void CapElevationPlane(Tile& tile, int start, int len, double cap) {
  double* w = tile.w().data() + start;
  for (int j = 0; j < len; ++j) {
    if (w[j] > cap) tile.ScaleCell(start + j, cap / w[j]);
  }
}

// Adds one observation y, with gain g, to a run of a bgk-ll tile's cells: the kernel sums and
// the plane moments (Q only with dynamics: without, it stays 0 and is not touched).
template <bool kSecondMoment>
inline void AddPlaneRun(Tile& tile, int start, int len, const KernelStencil& ks, const double* k,
                        double g, double y) {
  double* __restrict w = tile.w().data() + start;
  double* __restrict s = tile.s().data() + start;
  double* __restrict q = tile.q().data() + start;
  double* __restrict su = tile.plane(Tile::kSu).data() + start;
  double* __restrict sv = tile.plane(Tile::kSv).data() + start;
  double* __restrict suu = tile.plane(Tile::kSuu).data() + start;
  double* __restrict suv = tile.plane(Tile::kSuv).data() + start;
  double* __restrict svv = tile.plane(Tile::kSvv).data() + start;
  double* __restrict suy = tile.plane(Tile::kSuy).data() + start;
  double* __restrict svy = tile.plane(Tile::kSvy).data() + start;
  const double* ku = ks.moments_at(0, k);
  const double* kv = ks.moments_at(1, k);
  const double* kuu = ks.moments_at(2, k);
  const double* kuv = ks.moments_at(3, k);
  const double* kvv = ks.moments_at(4, k);
  const double gy = g * y, gyy = gy * y;
  for (int j = 0; j < len; ++j) {
    w[j] += k[j] * g;
    s[j] += k[j] * gy;
    if constexpr (kSecondMoment) q[j] += k[j] * gyy;
    su[j] += ku[j] * g;
    sv[j] += kv[j] * g;
    suu[j] += kuu[j] * g;
    suv[j] += kuv[j] * g;
    svv[j] += kvv[j] * g;
    suy[j] += ku[j] * gy;
    svy[j] += kv[j] * gy;
  }
}

// The float sum of a scaled pair can land an ulp above `cap`: the slack makes capping
// idempotent, so a merge re-capping an already capped map changes nothing.
inline void CapBeta(float* a, float* b, int len, float cap) {
  const float limit = cap * (1.0f + 1e-5f);
  for (int j = 0; j < len; ++j) {
    const float sum = a[j] + b[j];
    if (sum > limit) {
      const float f = cap / sum;
      a[j] *= f;
      b[j] *= f;
    }
  }
}

}  // namespace bgkmap::internal
