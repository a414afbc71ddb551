#include "bgkmap/sim/odometry_drift.h"

#include <Eigen/Geometry>
#include <random>

namespace bgkmap::sim {

std::vector<Pose> DriftedOdometry(const std::vector<Pose>& truth, const DriftOptions& options) {
  std::vector<Pose> out;
  if (truth.empty()) return out;
  out.push_back(truth.front());
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (size_t k = 1; k < truth.size(); ++k) {
    // The true step in the previous sensor frame, then its error.
    const Pose& a = truth[k - 1];
    const Pose& b = truth[k];
    Eigen::Matrix3d step_r = a.rotation.transpose() * b.rotation;
    Eigen::Vector3d step_t = a.rotation.transpose() * (b.translation - a.translation);
    const double d = step_t.norm();
    step_t += Eigen::Vector3d(normal(rng), normal(rng), 0.2 * normal(rng)) *
              (options.translation_per_m * d);
    step_r = Eigen::AngleAxisd(options.yaw_per_m * d * normal(rng), Eigen::Vector3d::UnitZ())
                 .toRotationMatrix() *
             step_r;
    const Pose& prev = out.back();
    Pose next;
    next.rotation = prev.rotation * step_r;
    next.translation = prev.translation + prev.rotation * step_t;
    // Keep the rotation orthonormal despite rounding over thousands of steps.
    next.rotation = Eigen::Quaterniond(next.rotation).normalized().toRotationMatrix();
    out.push_back(next);
  }
  return out;
}

}  // namespace bgkmap::sim
