// PoseHistory: the velocity a hand's recent poses show (what a released object leaves with).
#include "physics_backend/pose_history.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

namespace edgephys::physics {
namespace {

Quatf FromEigen(const Eigen::Quaterniond& q) {
  return {static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()),
          static_cast<float>(q.w())};
}

float Norm(const Vec3f& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }
Vec3f Minus(const Vec3f& a, const Eigen::Vector3d& b) {
  return {static_cast<float>(a.x - b.x()), static_cast<float>(a.y - b.y()),
          static_cast<float>(a.z - b.z())};
}

// Constant linear and angular velocity, sampled at irregular times (gaps 4-30 ms, as poses
// reach a relay): the least-squares slopes are the velocities, whatever the spacing.
TEST(PoseHistory, ConstantMotionAtIrregularTimesGivesItsVelocity) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1), gap(0.004, 0.030);
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d p0(u(rng), 1 + u(rng), u(rng)), v(3 * u(rng), 3 * u(rng), 3 * u(rng));
    const Eigen::Vector3d w(4 * u(rng), 4 * u(rng), 4 * u(rng));
    const Eigen::Quaterniond q0 =
        Eigen::Quaterniond(Eigen::AngleAxisd(3 * u(rng), Eigen::Vector3d(u(rng), u(rng), 1).normalized()));
    PoseHistory h;
    double t = 100 + 10 * u(rng);
    for (int i = 0; i < 12; ++i) {
      t += gap(rng);
      const Eigen::Vector3d p = p0 + v * (t - 100);
      // World-frame angular velocity: q(t) = exp(w t) q0.
      const Eigen::Quaterniond q =
          (w.norm() > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(w.norm() * (t - 100), w.normalized()))
                        : Eigen::Quaterniond::Identity()) *
          q0;
      h.Add(t, {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())},
            FromEigen(q));
    }
    Vec3f lin, ang;
    ASSERT_TRUE(h.Estimate(0.1, &lin, &ang)) << trial;
    // Floats hold positions to ~1e-7 m and quaternions to ~1e-7: over >= 33 ms that is ~1e-4.
    EXPECT_LT(Norm(Minus(lin, v)), 2e-3 + 1e-3 * v.norm()) << trial;
    EXPECT_LT(Norm(Minus(ang, w)), 5e-3 + 1e-3 * w.norm()) << trial;
  }
}

// Position noise of +-0.5 mm (a tracker's) over 6 poses in 100 ms: the velocity within a few
// centimetres a second, where the last two poses alone would be off by up to 6 cm/s.
TEST(PoseHistory, NoisyPositionsAverageOut) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> noise(-0.0005f, 0.0005f);
  double worst = 0;
  for (int trial = 0; trial < 200; ++trial) {
    PoseHistory h;
    for (int i = 0; i < 8; ++i) {
      const double t = i / 60.0;
      h.Add(t, {0.6f * static_cast<float>(t) + noise(rng), 1 + noise(rng), noise(rng)}, {});
    }
    Vec3f lin, ang;
    ASSERT_TRUE(h.Estimate(0.1, &lin, &ang));
    worst = std::max(worst, static_cast<double>(Norm({lin.x - 0.6f, lin.y, lin.z})));
  }
  EXPECT_LT(worst, 0.04);
}

TEST(PoseHistory, TooFewPosesOrTooShortASpanGiveNoEstimate) {
  PoseHistory h;
  Vec3f lin{9, 9, 9}, ang{9, 9, 9};
  EXPECT_FALSE(h.Estimate(0.1, &lin, &ang));
  h.Add(1.00, {0, 0, 0}, {});
  h.Add(1.01, {0.01f, 0, 0}, {});
  EXPECT_FALSE(h.Estimate(0.1, &lin, &ang)) << "two poses";
  h.Add(1.02, {0.02f, 0, 0}, {});
  EXPECT_FALSE(h.Estimate(0.1, &lin, &ang)) << "20 ms is under a third of 100 ms";
  h.Add(1.04, {0.04f, 0, 0}, {});
  ASSERT_TRUE(h.Estimate(0.1, &lin, &ang));
  EXPECT_NEAR(lin.x, 1.0f, 1e-3f);
  // Poses older than the window are not used: a jump 1 s ago does not count.
  PoseHistory g;
  g.Add(0.0, {5, 0, 0}, {});
  for (int i = 0; i < 5; ++i) g.Add(1.0 + 0.02 * i, {0, 0, 0}, {});
  ASSERT_TRUE(g.Estimate(0.1, &lin, &ang));
  EXPECT_NEAR(Norm(lin), 0.0f, 1e-6f);
  EXPECT_FALSE(g.Estimate(0, &lin, &ang)) << "no window";
  EXPECT_FALSE(g.Estimate(std::nan(""), &lin, &ang));
  EXPECT_EQ(lin.x, 0.0f) << "outputs untouched on failure";
}

TEST(PoseHistory, LateAndNonFiniteTimesAreIgnoredAndASameTimePoseReplaces) {
  PoseHistory h;
  h.Add(1.00, {0, 0, 0}, {});
  h.Add(1.02, {0.02f, 0, 0}, {});
  h.Add(1.01, {7, 7, 7}, {});  // reordered: older than the newest
  h.Add(std::numeric_limits<double>::infinity(), {7, 7, 7}, {});
  h.Add(std::nan(""), {7, 7, 7}, {});
  EXPECT_EQ(h.size(), 2u);
  h.Add(1.04, {9, 9, 9}, {});
  h.Add(1.04, {0.04f, 0, 0}, {});  // a later update for the same instant
  EXPECT_EQ(h.size(), 3u);
  Vec3f lin, ang;
  ASSERT_TRUE(h.Estimate(0.1, &lin, &ang));
  EXPECT_NEAR(lin.x, 1.0f, 1e-3f);
  EXPECT_NEAR(lin.y, 0.0f, 1e-3f);
  double t;
  Vec3f p;
  Quatf q;
  ASSERT_TRUE(h.Newest(&t, &p, &q));
  EXPECT_EQ(t, 1.04);
  EXPECT_EQ(p.x, 0.04f);
  // The ring keeps the newest kCapacity poses.
  for (int i = 0; i < 20; ++i) h.Add(2.0 + 0.01 * i, {static_cast<float>(0.01 * i), 0, 0}, {});
  EXPECT_EQ(h.size(), PoseHistory::kCapacity);
  ASSERT_TRUE(h.Estimate(0.1, &lin, &ang));
  EXPECT_NEAR(lin.x, 1.0f, 1e-3f);
}

}  // namespace
}  // namespace edgephys::physics
