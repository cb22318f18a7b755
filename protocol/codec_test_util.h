// Test-only helpers shared by the format-2 codec tests: random transforms and error metrics.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include "protocol/state_codec.h"

namespace edgephys::testing_util {

inline Quatf RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  double q[4] = {n(rng), n(rng), n(rng), n(rng)};
  double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  return {static_cast<float>(q[0] / len), static_cast<float>(q[1] / len),
          static_cast<float>(q[2] / len), static_cast<float>(q[3] / len)};
}

// Rotation angle between two unit quaternions, degrees (precise near zero).
inline double RotationErrorDeg(const Quatf& a, const Quatf& b) {
  // r = conj(a) * b
  const double ax = -a.x, ay = -a.y, az = -a.z, aw = a.w;
  const double rx = aw * b.x + ax * b.w + ay * b.z - az * b.y;
  const double ry = aw * b.y - ax * b.z + ay * b.w + az * b.x;
  const double rz = aw * b.z + ax * b.y - ay * b.x + az * b.w;
  const double rw = aw * b.w - ax * b.x - ay * b.y - az * b.z;
  const double v = std::sqrt(rx * rx + ry * ry + rz * rz);
  return 2.0 * std::atan2(v, std::fabs(rw)) * 180.0 / 3.14159265358979323846;
}

inline double PositionError(const Vec3f& a, const Vec3f& b) {
  const double dx = static_cast<double>(a.x) - b.x, dy = static_cast<double>(a.y) - b.y,
               dz = static_cast<double>(a.z) - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// float32 rounding slack of a coordinate of magnitude `m` (metres), Euclidean over 3 axes.
inline double FloatSlack(double m) { return 3.0 * std::ldexp(std::fabs(m) + 1.0, -23); }

inline constexpr double kMotionPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// Test motion: smooth paths at a given speed, spinning about a slowly varying axis. Two
// families (integrated wandering heading; Lissajous), parameters drawn from the seed.
class TestMotion {
 public:
  TestMotion(uint64_t seed, uint32_t index, double speed, double spin_dps, int family)
      : family_(family), speed_(speed) {
    std::mt19937_64 rng(seed * 7919 + index);
    std::uniform_real_distribution<double> u(0, 1);
    pos_[0] = (index % 16) * 4.0 - 30;
    pos_[1] = 1.0 + u(rng);
    pos_[2] = (index / 16) * 4.0 - 30;
    heading_ = 2 * kMotionPi * u(rng);
    turn_amp_ = 0.3 + 0.9 * u(rng);  // rad/s: radius of curvature down to ~1.25 m at 1.5 m/s
    turn_freq_ = 0.2 + 0.6 * u(rng);
    turn_phase_ = 2 * kMotionPi * u(rng);
    climb_phase_ = 2 * kMotionPi * u(rng);
    for (int i = 0; i < 3; ++i) lis_w_[i] = 0.6 + 0.8 * u(rng), lis_p_[i] = 2 * kMotionPi * u(rng);
    const double n = std::sqrt(
        (lis_w_[0] * lis_w_[0] + 0.25 * lis_w_[1] * lis_w_[1] + lis_w_[2] * lis_w_[2]) / 2.0);
    lis_a_ = speed / n;
    spin_ = spin_dps * kMotionPi / 180.0;
    axis_tilt_ = 0.3 + 1.0 * u(rng);
    axis_rate_ = 0.1 + 0.4 * u(rng);
    axis_phase_ = 2 * kMotionPi * u(rng);
    std::normal_distribution<double> nd;
    double q[4] = {nd(rng), nd(rng), nd(rng), nd(rng)};
    const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; ++i) q_[i] = q[i] / qn;
    origin_[0] = pos_[0], origin_[1] = pos_[1], origin_[2] = pos_[2];
  }

  // Advances (1 ms integration steps) to `t` seconds and returns the truth.
  EntityState AdvanceTo(double t) {
    while (t_ + 1e-9 < t) {
      const double dt = std::min(0.001, t - t_);
      Step(dt);
    }
    EntityState s;
    if (family_ == 1) {
      s.position = {
          static_cast<float>(origin_[0] + lis_a_ * std::sin(lis_w_[0] * t + lis_p_[0])),
          static_cast<float>(origin_[1] + 0.5 * lis_a_ * std::sin(lis_w_[1] * t + lis_p_[1])),
          static_cast<float>(origin_[2] + lis_a_ * std::sin(lis_w_[2] * t + lis_p_[2]))};
    } else {
      s.position = {static_cast<float>(pos_[0]), static_cast<float>(pos_[1]),
                    static_cast<float>(pos_[2])};
    }
    s.rotation = {static_cast<float>(q_[0]), static_cast<float>(q_[1]), static_cast<float>(q_[2]),
                  static_cast<float>(q_[3])};
    return s;
  }

  void Teleport(double dx) { pos_[0] += dx, origin_[0] += dx; }

 private:
  void Step(double dt) {
    const double tm = t_ + dt / 2;
    // Wandering heading at constant speed, gentle climb.
    const double turn = turn_amp_ * std::sin(turn_freq_ * tm + turn_phase_);
    const double climb = 0.15 * std::sin(0.5 * tm + climb_phase_);
    const double dir[3] = {std::cos(heading_ + turn * dt / 2) * std::cos(climb), std::sin(climb),
                           std::sin(heading_ + turn * dt / 2) * std::cos(climb)};
    for (int i = 0; i < 3; ++i) pos_[i] += speed_ * dt * dir[i];
    heading_ += turn * dt;
    // Spin about an axis precessing slowly around +y.
    const double th = axis_phase_ + axis_rate_ * tm;
    const double ax[3] = {std::sin(axis_tilt_) * std::cos(th), std::cos(axis_tilt_),
                          std::sin(axis_tilt_) * std::sin(th)};
    const double half = spin_ * dt / 2, s = std::sin(half), c = std::cos(half);
    const double d[4] = {ax[0] * s, ax[1] * s, ax[2] * s, c};
    // q = d * q (world-frame angular velocity)
    const double x = d[3] * q_[0] + d[0] * q_[3] + d[1] * q_[2] - d[2] * q_[1];
    const double y = d[3] * q_[1] - d[0] * q_[2] + d[1] * q_[3] + d[2] * q_[0];
    const double z = d[3] * q_[2] + d[0] * q_[1] - d[1] * q_[0] + d[2] * q_[3];
    const double w = d[3] * q_[3] - d[0] * q_[0] - d[1] * q_[1] - d[2] * q_[2];
    const double n = std::sqrt(x * x + y * y + z * z + w * w);
    q_[0] = x / n, q_[1] = y / n, q_[2] = z / n, q_[3] = w / n;
    t_ += dt;
  }

  int family_;
  double speed_;
  double t_ = 0;
  double pos_[3], origin_[3];
  double heading_, turn_amp_, turn_freq_, turn_phase_, climb_phase_;
  double lis_w_[3], lis_p_[3], lis_a_;
  double spin_, axis_tilt_, axis_rate_, axis_phase_;
  double q_[4];
};

}  // namespace edgephys::testing_util
