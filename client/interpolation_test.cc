#include "client/interpolation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "client/snapshot_buffer.h"

namespace edgephys {
namespace {

using Eigen::AngleAxisf;
using Eigen::Quaternionf;
using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;
constexpr std::array<Interpolator, 5> kAll = {Interpolator::kLerpSlerp, Interpolator::kDualQuatDlb,
                                              Interpolator::kDualQuatSclerp, Interpolator::kHermite,
                                              Interpolator::kNone};
constexpr std::array<Interpolator, 4> kSmooth = {
    Interpolator::kLerpSlerp, Interpolator::kDualQuatDlb, Interpolator::kDualQuatSclerp,
    Interpolator::kHermite};

// An analytic motion: pose and its world-frame velocities at time t (seconds).
struct Motion {
  std::function<Pose(double)> pose;
  std::function<Vec3f(double)> linear_velocity;
  std::function<Vec3f(double)> angular_velocity;
};

Pose MakePose(const Vector3f& p, const Quaternionf& q) {
  return {FromEigen(p), FromEigen(q.normalized())};
}

// Constant velocity along a line, constant (non-trivial) orientation.
Motion LineMotion() {
  const Vector3f p0(1, 2, 3), v(2, -1, 0.5f);
  const Quaternionf q(AngleAxisf(0.5f, Vector3f(1, 1, 0).normalized()));
  return {[=](double t) { return MakePose(p0 + v * static_cast<float>(t), q); },
          [=](double) { return FromEigen(v); }, [](double) { return Vec3f{}; }};
}

// Rotation about a fixed axis through the body's own (fixed) position.
Motion SpinMotion(float omega) {
  const Vector3f p(1, 2, 3), axis = Vector3f(1, 2, 2).normalized();
  const Quaternionf q0(AngleAxisf(0.3f, Vector3f::UnitX()));
  return {[=](double t) {
            return MakePose(p, Quaternionf(AngleAxisf(static_cast<float>(omega * t), axis)) * q0);
          },
          [](double) { return Vec3f{}; }, [=](double) { return FromEigen(axis * omega); }};
}

// Uniform screw motion: rotation at `omega` about the axis through `c` along `axis`, and
// translation at `v_par` along it. The body starts `radius` from the axis.
Motion ScrewMotion(float omega, float radius, float v_par) {
  const Vector3f axis = Vector3f(0.2f, 1, 0.3f).normalized();
  const Vector3f c(0.5f, 1.0f, -0.5f);
  const Vector3f offset = axis.unitOrthogonal() * radius;  // body position relative to c at t=0
  const Quaternionf q0(AngleAxisf(0.7f, Vector3f(1, 0, 1).normalized()));
  auto rot = [=](double t) { return Quaternionf(AngleAxisf(static_cast<float>(omega * t), axis)); };
  return {[=](double t) {
            const Quaternionf r = rot(t);
            return MakePose(c + r * offset + axis * static_cast<float>(v_par * t), r * q0);
          },
          [=](double t) { return FromEigen(omega * axis.cross(rot(t) * offset) + v_par * axis); },
          [=](double) { return FromEigen(axis * omega); }};
}

// Circle of `radius` (a screw of zero pitch), the body turning with the path.
Motion CircleMotion(float omega, float radius) { return ScrewMotion(omega, radius, 0.0f); }

struct Fill {
  double t0 = 100.0;  // a non-zero sender epoch
  double dt = 1.0 / 30;
  int count = 30;
  bool velocities = false;
};

SnapshotBuffer MakeBuffer(const Motion& m, const Fill& f, size_t capacity = 64) {
  SnapshotBuffer buffer(SnapshotBufferConfig{.capacity = capacity});
  for (int i = 0; i < f.count; ++i) {
    const double t = f.t0 + i * f.dt;
    const Pose p = m.pose(t - f.t0);
    Snapshot s{.sender_time_s = t, .position = p.position, .rotation = p.rotation};
    if (f.velocities) {
      s.has_linear_velocity = s.has_angular_velocity = true;
      s.linear_velocity = m.linear_velocity(t - f.t0);
      s.angular_velocity = m.angular_velocity(t - f.t0);
    }
    EXPECT_EQ(buffer.Insert(s, t), InsertResult::kInserted);
  }
  return buffer;
}

// Worst error over sample points strictly inside the filled range (segments 1..count-2, so
// that every method has neighbours), 16 points per segment.
PoseError MaxInteriorError(const SnapshotBuffer& b, const Motion& m, const Fill& f,
                           Interpolator method) {
  PoseError worst;
  for (int seg = 1; seg + 2 < f.count; ++seg) {
    for (int k = 0; k < 16; ++k) {
      const double t = f.t0 + (seg + k / 16.0) * f.dt;
      const PoseError e = Compare(Sample(b, t, method), m.pose(t - f.t0));
      worst.pos_m = std::max(worst.pos_m, e.pos_m);
      worst.rot_deg = std::max(worst.rot_deg, e.rot_deg);
    }
  }
  return worst;
}

void Report(const char* motion, Interpolator method, const PoseError& e) {
  std::printf("[accuracy] %-14s %-10s pos %.3e m  rot %.3e deg\n", motion, InterpolatorName(method),
              e.pos_m, e.rot_deg);
}

bool IsFinite(const Pose& p) {
  return std::isfinite(p.position.x) && std::isfinite(p.position.y) &&
         std::isfinite(p.position.z) && std::isfinite(p.rotation.x) &&
         std::isfinite(p.rotation.y) && std::isfinite(p.rotation.z) && std::isfinite(p.rotation.w);
}

// Float round-off allowance: positions here are within ~10 m, so a few ulps are ~1e-5 m.
constexpr double kPosEps = 2e-5;
constexpr double kRotEpsDeg = 2e-3;

// --- DualQuaternion ---

TEST(DualQuaternionTest, RoundTripsPoseAndComposesLikeTransforms) {
  const Quaternionf ra(AngleAxisf(0.8f, Vector3f(1, 2, 3).normalized()));
  const Quaternionf rb(AngleAxisf(-1.3f, Vector3f(0, 1, 0)));
  const Vector3f ta(1, -2, 0.5f), tb(0.3f, 0.1f, 4);
  const DualQuaternion a = DualQuaternion::FromRigid(ra, ta);
  const DualQuaternion b = DualQuaternion::FromRigid(rb, tb);
  EXPECT_LT((a.translation() - ta).norm(), 1e-6);
  EXPECT_LT(a.rotation().angularDistance(ra), 1e-6);
  const Vector3f x(0.7f, -0.2f, 2.0f);
  EXPECT_LT(((a * b).TransformPoint(x) - a.TransformPoint(b.TransformPoint(x))).norm(), 1e-5);
  EXPECT_LT(((a.Conjugate() * a).TransformPoint(x) - x).norm(), 1e-5);
}

TEST(DualQuaternionTest, PowIsAOneParameterGroup) {
  const DualQuaternion s = DualQuaternion::FromRigid(
      Quaternionf(AngleAxisf(1.1f, Vector3f(1, 0, 1).normalized())), Vector3f(0.4f, 2, -1));
  const Vector3f x(1, 2, 3);
  EXPECT_LT((s.Pow(1).TransformPoint(x) - s.TransformPoint(x)).norm(), 1e-5);
  EXPECT_LT((s.Pow(0).TransformPoint(x) - x).norm(), 1e-6);
  const DualQuaternion half = s.Pow(0.5f);
  EXPECT_LT(((half * half).TransformPoint(x) - s.TransformPoint(x)).norm(), 1e-5);
  const DualQuaternion third = s.Pow(1.0f / 3);
  EXPECT_LT(((third * third * third).TransformPoint(x) - s.TransformPoint(x)).norm(), 2e-5);
  // Extrapolation: s^2 = s * s.
  EXPECT_LT((s.Pow(2).TransformPoint(x) - (s * s).TransformPoint(x)).norm(), 2e-5);
  // Pure translation (zero angle) and tiny angles are stable.
  const DualQuaternion t = DualQuaternion::FromRigid(Quaternionf::Identity(), Vector3f(2, 0, 0));
  EXPECT_LT((t.Pow(0.25f).translation() - Vector3f(0.5f, 0, 0)).norm(), 1e-6);
  const DualQuaternion tiny = DualQuaternion::FromRigid(
      Quaternionf(AngleAxisf(1e-6f, Vector3f::UnitZ())), Vector3f(2, 0, 0));
  EXPECT_LT((tiny.Pow(0.5f).translation() - Vector3f(1, 0, 0)).norm(), 1e-5);
}

// --- Analytic motions ---

TEST(InterpolationAccuracyTest, ConstantVelocityLineIsExactForAllSmoothInterpolators) {
  const Motion m = LineMotion();
  for (bool velocities : {false, true}) {
    const Fill f{.velocities = velocities};
    const SnapshotBuffer b = MakeBuffer(m, f);
    for (Interpolator method : kSmooth) {
      const PoseError e = MaxInteriorError(b, m, f, method);
      if (!velocities) Report("line", method, e);
      EXPECT_LT(e.pos_m, kPosEps) << InterpolatorName(method);
      EXPECT_LT(e.rot_deg, kRotEpsDeg) << InterpolatorName(method);
    }
  }
}

TEST(InterpolationAccuracyTest, HoldLastIsAStepFunction) {
  const Motion m = LineMotion();
  const Fill f;
  const SnapshotBuffer b = MakeBuffer(m, f);
  const double t = f.t0 + 5.7 * f.dt;
  const PoseError e = Compare(Sample(b, t, Interpolator::kNone), m.pose(5 * f.dt));
  EXPECT_LT(e.pos_m, 1e-6);
  EXPECT_LT(e.rot_deg, 1e-4);
}

TEST(InterpolationAccuracyTest, UniformRotationAboutFixedAxis) {
  // 3 rad/s at 30 Hz: 0.1 rad (5.7 degrees) per segment.
  const Motion m = SpinMotion(3.0f);
  const Fill f;
  const SnapshotBuffer b = MakeBuffer(m, f);
  for (Interpolator method : kSmooth) {
    const PoseError e = MaxInteriorError(b, m, f, method);
    Report("spin", method, e);
    EXPECT_LT(e.pos_m, kPosEps) << InterpolatorName(method);
    if (method == Interpolator::kDualQuatDlb) {
      // DLB's rotation is a normalised lerp: right path, non-uniform rate. For a step of theta
      // the angle error is below theta^3 / 16 (0.1 rad -> 6.3e-5 rad, 3.6e-3 deg).
      EXPECT_LT(e.rot_deg, std::pow(0.1, 3) / 16 * 180 / kPi);
    } else {
      EXPECT_LT(e.rot_deg, kRotEpsDeg) << InterpolatorName(method);
    }
  }
}

TEST(InterpolationAccuracyTest, UniformScrewMotionOrdersSclerpDlbLerp) {
  // 2 rad/s about an axis 1.5 m away, 0.5 m/s along it, sent at 20 Hz: 0.1 rad per segment.
  const float omega = 2.0f, radius = 1.5f;
  const Motion m = ScrewMotion(omega, radius, 0.5f);
  const Fill f{.dt = 1.0 / 20};
  const SnapshotBuffer b = MakeBuffer(m, f);
  const double theta = omega * f.dt;
  const double sagitta = radius * theta * theta / 8;  // lerp's worst chord error: 1.9 mm

  const PoseError sclerp = MaxInteriorError(b, m, f, Interpolator::kDualQuatSclerp);
  const PoseError dlb = MaxInteriorError(b, m, f, Interpolator::kDualQuatDlb);
  const PoseError lerp = MaxInteriorError(b, m, f, Interpolator::kLerpSlerp);
  const PoseError hermite = MaxInteriorError(b, m, f, Interpolator::kHermite);
  Report("screw", Interpolator::kDualQuatSclerp, sclerp);
  Report("screw", Interpolator::kDualQuatDlb, dlb);
  Report("screw", Interpolator::kLerpSlerp, lerp);
  Report("screw", Interpolator::kHermite, hermite);

  EXPECT_LT(sclerp.pos_m, kPosEps);
  EXPECT_LT(sclerp.rot_deg, kRotEpsDeg);
  // DLB stays within theta^2/100 of the radius (2.3e-4 m here): an order below lerp's chord.
  EXPECT_LT(dlb.pos_m, radius * theta * theta / 100);
  EXPECT_LT(dlb.rot_deg, std::pow(theta, 3) / 16 * 180 / kPi);
  // Lerp+slerp cuts the chord: its error is the sagitta (within 10%).
  EXPECT_GT(lerp.pos_m, 0.9 * sagitta);
  EXPECT_LT(lerp.pos_m, 1.1 * sagitta);
  // The measured ordering.
  EXPECT_LT(sclerp.pos_m, dlb.pos_m);
  EXPECT_LT(dlb.pos_m, lerp.pos_m);
}

TEST(InterpolationAccuracyTest, CircularPathHermiteBeatsLerp) {
  // 1 m radius at 2 rad/s (2 m/s), 20 Hz: 0.1 rad per segment.
  const float omega = 2.0f, radius = 1.0f;
  const Motion m = CircleMotion(omega, radius);
  for (bool velocities : {false, true}) {
    const Fill f{.dt = 1.0 / 20, .velocities = velocities};
    const SnapshotBuffer b = MakeBuffer(m, f);
    const PoseError lerp = MaxInteriorError(b, m, f, Interpolator::kLerpSlerp);
    const PoseError hermite = MaxInteriorError(b, m, f, Interpolator::kHermite);
    Report(velocities ? "circle+vel" : "circle", Interpolator::kLerpSlerp, lerp);
    Report(velocities ? "circle+vel" : "circle", Interpolator::kHermite, hermite);
    if (!velocities) {
      Report("circle", Interpolator::kDualQuatDlb,
             MaxInteriorError(b, m, f, Interpolator::kDualQuatDlb));
      Report("circle", Interpolator::kDualQuatSclerp,
             MaxInteriorError(b, m, f, Interpolator::kDualQuatSclerp));
    }
    // Hermite's error is O(theta^4) against lerp's O(theta^2): at least 10x smaller here.
    EXPECT_LT(hermite.pos_m * 10, lerp.pos_m) << "velocities=" << velocities;
    EXPECT_LT(hermite.rot_deg, kRotEpsDeg);
  }
}

// --- Loss and jitter through the jitter buffer ---

struct Packet {
  double arrival;
  Snapshot snapshot;
};

TEST(InterpolationRobustnessTest, LossAndJitterKeepErrorBoundedAndTimeMonotonic) {
  // Screw motion: 2 rad/s, 1 m from the axis, 0.3 m/s along it; sent at 30 Hz for 20 s from a
  // sender clock 1000 s ahead; 20% dropped; arrival = send + 60 ms +- 20 ms (uniform, so
  // packets reorder); rendered at 90 Hz.
  const float omega = 2.0f, radius = 1.0f, v_par = 0.3f;
  const Motion m = ScrewMotion(omega, radius, v_par);
  const double send_dt = 1.0 / 30, sender_epoch = 1000.0;
  const double accel = omega * omega * radius;             // |p''| = 4 m/s^2
  const double speed = std::hypot(omega * radius, v_par);  // |p'|
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Packet> packets;
  int dropped = 0;
  for (int i = 0; i < 600; ++i) {
    const double t = i * send_dt;
    if (unit(rng) < 0.2) {
      ++dropped;
      continue;
    }
    const Pose p = m.pose(t);
    packets.push_back(
        {t + 0.060 + (unit(rng) - 0.5) * 0.040,
         Snapshot{
             .sender_time_s = sender_epoch + t, .position = p.position, .rotation = p.rotation}});
  }
  std::stable_sort(packets.begin(), packets.end(),
                   [](const Packet& a, const Packet& b) { return a.arrival < b.arrival; });

  SnapshotBuffer buffer;
  SampleOptions options;
  size_t next = 0;
  double last_render = -1e300;
  std::array<double, 5> last_phase;
  last_phase.fill(-1e300);
  std::array<PoseError, 5> worst{};
  std::array<double, 5> worst_ratio{};  // error / per-frame bound
  int frames = 0, extrapolated = 0;
  const Vector3f axis = Vector3f(0.2f, 1, 0.3f).normalized();
  const Quaternionf q0 = ToEigen(m.pose(0).rotation);
  for (double now = 0.5; now < 20.0; now += 1.0 / 90) {
    while (next < packets.size() && packets[next].arrival <= now) {
      buffer.Insert(packets[next].snapshot, packets[next].arrival);
      ++next;
    }
    const double render = buffer.RenderTime(now);
    ASSERT_GE(render, last_render) << "render time went backwards at " << now;
    last_render = render;
    if (now < 2.0) continue;  // let the estimators settle

    // The bracketing gap h and the extrapolation distance decide the analytic bound.
    ++frames;
    const double newest = buffer.newest().sender_time_s;
    const size_t i1 = buffer.UpperBound(render);
    double pos_bound, rot_bound_deg;
    if (render >= newest) {
      ++extrapolated;
      const double h = buffer.size() >= 2 ? newest - buffer[buffer.size() - 2].sender_time_s : 0;
      const double late = render - newest;
      const double e = std::min(late, options.max_extrapolation_s);
      // Linear continuation error a/2 * e * (e + h), plus motion after the hold.
      pos_bound = accel / 2 * e * (e + h) + speed * (late - e);
      rot_bound_deg = omega * (late - e) * 180 / kPi;
    } else {
      const double h = buffer[i1].sender_time_s - buffer[i1 - 1].sender_time_s;
      pos_bound = accel * h * h / 8;  // |p''| h^2 / 8: the linear-interpolation bound
      rot_bound_deg = std::pow(omega * h, 3) / 16 * 180 / kPi;  // DLB's nlerp rate error
    }
    const Pose truth = m.pose(render - sender_epoch);
    for (size_t k = 0; k < kAll.size(); ++k) {
      const Pose pose = Sample(buffer, render, kAll[k], options);
      ASSERT_TRUE(IsFinite(pose)) << InterpolatorName(kAll[k]);
      const PoseError e = Compare(pose, truth);
      worst[k].pos_m = std::max(worst[k].pos_m, e.pos_m);
      worst[k].rot_deg = std::max(worst[k].rot_deg, e.rot_deg);
      if (kAll[k] == Interpolator::kNone) {
        // Hold-last lags by at most the bracketing gap plus the lateness.
        const double lag = render - buffer[i1 == 0 ? 0 : i1 - 1].sender_time_s;
        EXPECT_LE(e.pos_m, speed * lag + kPosEps);
      } else {
        EXPECT_LE(e.pos_m, pos_bound + kPosEps) << InterpolatorName(kAll[k]) << " at " << now;
        EXPECT_LE(e.rot_deg, rot_bound_deg + 0.01) << InterpolatorName(kAll[k]) << " at " << now;
        worst_ratio[k] = std::max(worst_ratio[k], e.pos_m / (pos_bound + kPosEps));
      }
      // The phase about the screw axis must never decrease: no backwards motion on screen.
      const Quaternionf rel = ToEigen(pose.rotation) * q0.conjugate();
      double phase = 2 * std::atan2(rel.vec().dot(axis), rel.w());
      while (phase < last_phase[k] - kPi) phase += 2 * kPi;
      EXPECT_GE(phase, last_phase[k] - 1e-4) << InterpolatorName(kAll[k]) << " at " << now;
      last_phase[k] = std::max(last_phase[k], phase);
    }
  }
  std::printf("[loss+jitter] dropped %d/600, frames %d, extrapolated %d, delay %.1f ms\n", dropped,
              frames, extrapolated, buffer.target_delay_s() * 1e3);
  for (size_t k = 0; k < kAll.size(); ++k) {
    std::printf("[loss+jitter] %-10s max pos %.3e m  max rot %.3e deg  max err/bound %.2f\n",
                InterpolatorName(kAll[k]), worst[k].pos_m, worst[k].rot_deg, worst_ratio[k]);
  }
  // Overall: the largest gap after 20% loss here stays well under 0.2 s, so the interpolating
  // frames are within a * 0.2^2 / 8 = 20 mm; the buffer keeps extrapolation rare.
  for (Interpolator method : kSmooth) {
    EXPECT_LT(worst[static_cast<size_t>(method)].pos_m, accel * 0.2 * 0.2 / 8);
  }
  EXPECT_LT(extrapolated, frames / 10);
}

// --- Degenerate inputs ---

TEST(InterpolationDegenerateTest, EmptyBufferGivesIdentity) {
  const SnapshotBuffer b;
  for (Interpolator method : kAll) {
    const Pose p = Sample(b, 1.0, method);
    EXPECT_EQ(p.position.x, 0);
    EXPECT_EQ(p.rotation.w, 1);
  }
}

TEST(InterpolationDegenerateTest, OneSnapshotHoldsOrExtrapolatesWithItsVelocity) {
  SnapshotBuffer b;
  const Quaternionf q(AngleAxisf(0.4f, Vector3f::UnitY()));
  b.Insert({.sender_time_s = 5.0, .position = {1, 2, 3}, .rotation = FromEigen(q)}, 5.0);
  for (Interpolator method : kAll) {
    for (double t : {-1e9, 4.0, 5.0, 5.05, 6.0, 1e12}) {
      const PoseError e = Compare(Sample(b, t, method), {{1, 2, 3}, FromEigen(q)});
      EXPECT_LT(e.pos_m, 1e-6) << InterpolatorName(method) << " t=" << t;
      EXPECT_LT(e.rot_deg, 1e-4) << InterpolatorName(method) << " t=" << t;
    }
  }
  // With a velocity it extrapolates up to 100 ms, then holds.
  SnapshotBuffer v;
  v.Insert({.sender_time_s = 5.0,
            .position = {1, 2, 3},
            .rotation = FromEigen(q),
            .has_linear_velocity = true,
            .linear_velocity = {1, 0, 0}},
           5.0);
  for (Interpolator method : kSmooth) {
    EXPECT_NEAR(Sample(v, 5.05, method).position.x, 1.05f, 1e-5) << InterpolatorName(method);
    EXPECT_NEAR(Sample(v, 7.0, method).position.x, 1.1f, 1e-5) << InterpolatorName(method);
    EXPECT_NEAR(Sample(v, 1e300, method).position.x, 1.1f, 1e-5) << InterpolatorName(method);
  }
  EXPECT_EQ(Sample(v, 7.0, Interpolator::kNone).position.x, 1.0f);
}

TEST(InterpolationDegenerateTest, IdenticalAndNearlyIdenticalTimestamps) {
  SnapshotBuffer b;
  EXPECT_EQ(b.Insert({.sender_time_s = 1.0, .position = {0, 0, 0}}, 1.0), InsertResult::kInserted);
  EXPECT_EQ(b.Insert({.sender_time_s = 1.0, .position = {5, 0, 0}}, 1.0), InsertResult::kDuplicate);
  // 2 microseconds later, 1 m away: interpolation is defined, velocity estimation refuses the
  // gap (below min_velocity_gap_s), so extrapolation holds instead of shooting off.
  EXPECT_EQ(b.Insert({.sender_time_s = 1.000002, .position = {1, 0, 0}}, 1.0),
            InsertResult::kInserted);
  for (Interpolator method : kAll) {
    for (double t : {0.5, 1.0, 1.000001, 1.000002, 1.05, 2.0}) {
      const Pose p = Sample(b, t, method);
      ASSERT_TRUE(IsFinite(p)) << InterpolatorName(method);
      EXPECT_GE(p.position.x, -1e-6f) << InterpolatorName(method) << " t=" << t;
      EXPECT_LE(p.position.x, 1.0f + 1e-6f) << InterpolatorName(method) << " t=" << t;
    }
  }
}

TEST(InterpolationDegenerateTest, AntipodalQuaternionsInterpolateTheShortWay) {
  const Quaternionf q(AngleAxisf(1.0f, Vector3f(1, 2, 3).normalized()));
  Quaternionf minus_q;
  minus_q.coeffs() = -q.coeffs();
  // Same rotation with opposite signs: nothing may spin.
  {
    SnapshotBuffer b;
    for (int i = 0; i < 4; ++i) {
      b.Insert({.sender_time_s = i * 0.1,
                .position = {0, 0, 0},
                .rotation = FromEigen(i % 2 ? minus_q : q)},
               i * 0.1);
    }
    for (Interpolator method : kAll) {
      for (double t : {0.05, 0.125, 0.15, 0.25, 0.33}) {
        const PoseError e = Compare(Sample(b, t, method), {{0, 0, 0}, FromEigen(q)});
        EXPECT_LT(e.rot_deg, kRotEpsDeg) << InterpolatorName(method) << " t=" << t;
        EXPECT_LT(e.pos_m, 1e-6) << InterpolatorName(method);
      }
    }
  }
  // 10 degrees to the negated 30 degrees about z: the midpoint is 20 degrees, not 200.
  {
    SnapshotBuffer b;
    const Quaternionf a(AngleAxisf(10 * kPi / 180, Vector3f::UnitZ()));
    Quaternionf c(AngleAxisf(30 * kPi / 180, Vector3f::UnitZ()));
    c.coeffs() = -c.coeffs();
    b.Insert({.sender_time_s = 0, .position = {1, 0, 0}, .rotation = FromEigen(a)}, 0);
    b.Insert({.sender_time_s = 1, .position = {1, 0, 0}, .rotation = FromEigen(c)}, 1);
    const Quaternionf mid(AngleAxisf(20 * kPi / 180, Vector3f::UnitZ()));
    for (Interpolator method : kSmooth) {
      const PoseError e = Compare(Sample(b, 0.5, method), {{1, 0, 0}, FromEigen(mid)});
      EXPECT_LT(e.rot_deg, 0.01) << InterpolatorName(method);
      EXPECT_LT(e.pos_m, 1e-5) << InterpolatorName(method);
    }
  }
}

TEST(InterpolationDegenerateTest, HugeTimeGapsNeitherOvershootNorRunAway) {
  SnapshotBuffer b;
  b.Insert({.sender_time_s = 0.0, .position = {0, 0, 0}}, 0.0);
  b.Insert({.sender_time_s = 1.0 / 30, .position = {0.1f, 0, 0}}, 1.0 / 30);  // 3 m/s
  b.Insert({.sender_time_s = 1e6, .position = {10, 0, 0}}, 1e6);
  b.Insert({.sender_time_s = 1e6 + 1.0 / 30, .position = {10.1f, 0, 0}}, 1e6 + 1.0 / 30);
  for (Interpolator method : kAll) {
    for (double t : {0.02, 1.0, 5e5, 1e6 - 1, 1e6 + 0.02, 1e6 + 0.05, 1e9, 1e300}) {
      const Pose p = Sample(b, t, method);
      ASSERT_TRUE(IsFinite(p)) << InterpolatorName(method) << " t=" << t;
      // Within the hull of the data plus 100 ms of extrapolation at 3 m/s.
      EXPECT_GE(p.position.x, -1e-5f) << InterpolatorName(method) << " t=" << t;
      EXPECT_LE(p.position.x, 10.1f + 0.3f + 1e-4f) << InterpolatorName(method) << " t=" << t;
    }
    // Across the huge gap, progress is linear in time (no Hermite overshoot).
    EXPECT_NEAR(
        Sample(b, 5e5, method).position.x,
        method == Interpolator::kNone ? 0.1f : 0.1f + 9.9f * (5e5 - 1.0 / 30) / (1e6 - 1.0 / 30),
        1e-3)
        << InterpolatorName(method);
  }
}

TEST(InterpolationDegenerateTest, ExtrapolationIsBoundedThenHolds) {
  const Motion m = LineMotion();
  const Fill f;
  const SnapshotBuffer b = MakeBuffer(m, f);
  const double newest = f.t0 + (f.count - 1) * f.dt;
  for (Interpolator method : kSmooth) {
    // Within 100 ms a constant velocity is continued exactly...
    const PoseError near = Compare(Sample(b, newest + 0.05, method), m.pose(newest + 0.05 - f.t0));
    EXPECT_LT(near.pos_m, kPosEps) << InterpolatorName(method);
    // ...beyond it the pose holds at the 100 ms extrapolation.
    const PoseError held = Compare(Sample(b, newest + 3.0, method), m.pose(newest + 0.1 - f.t0));
    EXPECT_LT(held.pos_m, kPosEps) << InterpolatorName(method);
  }
}

TEST(InterpolationDegenerateTest, CompareIsSignInsensitive) {
  const Quaternionf q(AngleAxisf(0.9f, Vector3f(0, 0, 1)));
  Quaternionf minus_q;
  minus_q.coeffs() = -q.coeffs();
  EXPECT_LT(Compare({{}, FromEigen(q)}, {{}, FromEigen(minus_q)}).rot_deg, 1e-4);
  const Quaternionf r = q * Quaternionf(AngleAxisf(kPi / 2, Vector3f::UnitX()));
  EXPECT_NEAR(Compare({{}, FromEigen(q)}, {{}, FromEigen(r)}).rot_deg, 90.0, 1e-3);
  EXPECT_NEAR(Compare({{3, 0, 0}, {}}, {{0, 4, 0}, {}}).pos_m, 5.0, 1e-9);
}

}  // namespace
}  // namespace edgephys
