#include "bgkmap/sim/pose_noise.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

namespace bgkmap::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A stationary first-order Gauss-Markov process, one value per step.
class GaussMarkov {
 public:
  GaussMarkov(double sigma, double correlation_steps, std::mt19937_64& rng)
      : sigma_(sigma),
        a_(correlation_steps > 0 ? std::exp(-1.0 / correlation_steps) : 0.0),
        rng_(rng) {
    x_ = sigma_ * normal_(rng_);
  }
  double Next() {
    const double x = x_;
    x_ = a_ * x_ + std::sqrt(1.0 - a_ * a_) * sigma_ * normal_(rng_);
    return x;
  }

 private:
  double sigma_, a_, x_ = 0.0;
  std::mt19937_64& rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace

PoseNoiseOptions PoseNoiseOptions::Scaled(double s) const {
  PoseNoiseOptions o = *this;
  o.xy_m *= s;
  o.z_m *= s;
  o.roll_pitch_deg *= s;
  o.yaw_deg *= s;
  o.drift_z_m *= s;
  o.drift_roll_pitch_deg *= s;
  return o;
}

std::vector<Pose> PerturbPoses(const std::vector<Pose>& truth, const PoseNoiseOptions& o) {
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  GaussMarkov drift_z(o.drift_z_m, o.drift_scans, rng);
  GaussMarkov drift_roll(o.drift_roll_pitch_deg * kDeg, o.drift_scans, rng);
  GaussMarkov drift_pitch(o.drift_roll_pitch_deg * kDeg, o.drift_scans, rng);
  std::vector<Pose> out;
  out.reserve(truth.size());
  for (const Pose& t : truth) {
    const double roll = drift_roll.Next() + o.roll_pitch_deg * kDeg * normal(rng);
    const double pitch = drift_pitch.Next() + o.roll_pitch_deg * kDeg * normal(rng);
    const double yaw = o.yaw_deg * kDeg * normal(rng);
    const Eigen::Vector3d dt(o.xy_m * normal(rng), o.xy_m * normal(rng),
                             drift_z.Next() + o.z_m * normal(rng));
    const Eigen::Matrix3d dr = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
    Pose p;
    p.rotation = Eigen::Quaterniond(dr * t.rotation).normalized().toRotationMatrix();
    p.translation = t.translation + dt;
    out.push_back(p);
  }
  return out;
}

}  // namespace bgkmap::sim
