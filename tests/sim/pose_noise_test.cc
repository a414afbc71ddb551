// SLAM-like pose error (sim/pose_noise.h): none at scale 0, the same for the same seed, and of the
// sizes it promises: per-scan jitter that does not persist, a drift of z, roll and pitch that
// does (correlated over its correlation time), and no drift where none is asked for.
#include "bgkmap/sim/pose_noise.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace bgkmap::sim {
namespace {

std::vector<Pose> Straight(int n) {
  std::vector<Pose> poses(n);
  for (int k = 0; k < n; ++k) poses[k].translation = {1.0 * k, 2.0, 1.5};
  return poses;
}

double Roll(const Pose& p) { return std::atan2(p.rotation(2, 1), p.rotation(2, 2)); }

struct Moments {
  double sd = 0, lag1 = 0;  // standard deviation about 0, lag-1 autocorrelation
};
template <typename Fn>
Moments Measure(const std::vector<Pose>& poses, Fn value) {
  double s2 = 0, s11 = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    const double v = value(poses[k], k);
    s2 += v * v;
    if (k > 0) s11 += v * value(poses[k - 1], k - 1);
  }
  return {std::sqrt(s2 / poses.size()), s11 / s2};
}

TEST(PoseNoiseTest, ScaleZeroIsTheTruthAndASeedRepeats) {
  const std::vector<Pose> truth = Straight(50);
  const std::vector<Pose> none = PerturbPoses(truth, PoseNoiseOptions().Scaled(0.0));
  for (size_t k = 0; k < truth.size(); ++k) {
    EXPECT_TRUE(none[k].translation.isApprox(truth[k].translation, 1e-15));
    EXPECT_TRUE(none[k].rotation.isApprox(truth[k].rotation, 1e-15));
  }
  const std::vector<Pose> a = PerturbPoses(truth, PoseNoiseOptions());
  const std::vector<Pose> b = PerturbPoses(truth, PoseNoiseOptions());
  PoseNoiseOptions other;
  other.seed = 2;
  const std::vector<Pose> c = PerturbPoses(truth, other);
  EXPECT_EQ(a[10].translation, b[10].translation);
  EXPECT_NE(a[10].translation, c[10].translation);
  for (const Pose& p : a) {  // still rigid
    EXPECT_NEAR((p.rotation.transpose() * p.rotation - Eigen::Matrix3d::Identity()).norm(), 0,
                1e-12);
  }
}

TEST(PoseNoiseTest, JitterIsWhiteAndDriftIsSlow) {
  const int n = 20000;
  const std::vector<Pose> truth = Straight(n);
  // Jitter only: x errors of the asked size, uncorrelated from scan to scan.
  PoseNoiseOptions jitter;
  jitter.drift_z_m = jitter.drift_roll_pitch_deg = 0.0;
  const std::vector<Pose> j = PerturbPoses(truth, jitter);
  const Moments x = Measure(
      j, [&](const Pose& p, size_t k) { return p.translation.x() - truth[k].translation.x(); });
  EXPECT_NEAR(x.sd, 0.03, 0.002);
  EXPECT_NEAR(x.lag1, 0.0, 0.03);
  // Drift only: z and roll of the asked size, correlated over drift_scans.
  PoseNoiseOptions drift;
  drift.xy_m = drift.z_m = drift.roll_pitch_deg = drift.yaw_deg = 0.0;
  const std::vector<Pose> d = PerturbPoses(truth, drift);
  const Moments z = Measure(
      d, [&](const Pose& p, size_t k) { return p.translation.z() - truth[k].translation.z(); });
  EXPECT_NEAR(z.sd, 0.05, 0.01);
  EXPECT_NEAR(z.lag1, std::exp(-1.0 / 100.0), 0.01);
  const Moments roll = Measure(d, [](const Pose& p, size_t) { return Roll(p); });
  EXPECT_NEAR(roll.sd * 180.0 / std::numbers::pi, 0.2, 0.04);
  for (size_t k = 0; k < d.size(); ++k) {  // no horizontal error without jitter
    EXPECT_DOUBLE_EQ(d[k].translation.x(), truth[k].translation.x());
  }
}

}  // namespace
}  // namespace bgkmap::sim
