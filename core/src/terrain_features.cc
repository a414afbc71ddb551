#include "bgkmap/core/terrain_features.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace bgkmap {

TerrainFeatures ComputeFeatures(std::span<const PatchPoint> patch) {
  // Centre on the first point: the covariance is translation invariant and small coordinates
  // keep it accurate at UTM-sized offsets.
  const PatchPoint& o = patch.front();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  double zmin = patch.front().z, zmax = patch.front().z;
  for (const PatchPoint& p : patch) {
    const Eigen::Vector3d d(p.x - o.x, p.y - o.y, p.z - o.z);
    sum += d;
    outer.noalias() += d * d.transpose();
    zmin = std::min(zmin, p.z);
    zmax = std::max(zmax, p.z);
  }
  const double n = static_cast<double>(patch.size());
  const Eigen::Vector3d mean = sum / n;
  const Eigen::Matrix3d cov = outer / n - mean * mean.transpose();  // population covariance

  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(cov);
  const double smallest = std::max(0.0, eig.eigenvalues()(0));  // ascending order
  const Eigen::Vector3d normal = eig.eigenvectors().col(0);
  const double nz = std::min(1.0, std::abs(normal.z()));

  TerrainFeatures f;
  f.step = zmax - zmin;
  f.slope_deg = std::acos(nz) * 180.0 / std::numbers::pi;
  f.roughness = std::sqrt(smallest);
  return f;
}

TerrainFeatures DiscountPoseNoise(TerrainFeatures f, double sigma_z) {
  if (sigma_z <= 0) return f;
  f.step = DiscountStep(f.step, sigma_z);
  f.roughness = std::sqrt(std::max(0.0, f.roughness * f.roughness - sigma_z * sigma_z));
  return f;
}

double DiscountStep(double step, double sigma_z) {
  return sigma_z <= 0 ? step : std::max(0.0, step - 2.0 * std::numbers::sqrt2 * sigma_z);
}

double TraversabilityValue(const TerrainFeatures& f, const MapParams& p) {
  if (f.step > p.step_crit || f.slope_deg > p.slope_crit_deg || f.roughness > p.roughness_crit) {
    return 1.0;
  }
  const double v = p.weights[0] * f.step / p.step_crit +
                   p.weights[1] * f.slope_deg / p.slope_crit_deg +
                   p.weights[2] * f.roughness / p.roughness_crit;
  return std::clamp(v, 0.0, 1.0);
}

double InCellStepLimit(const MapParams& params) {
  constexpr double kDegree = std::numbers::pi / 180.0;
  return params.step_crit +
         params.resolution * std::sqrt(2.0) * std::tan(params.slope_crit_deg * kDegree);
}

}  // namespace bgkmap
