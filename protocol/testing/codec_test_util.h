// Test-only helpers shared by the format-2 codec tests: random transforms and error metrics.
#pragma once

#include <cmath>
#include <numbers>
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
  return 2.0 * std::atan2(v, std::fabs(rw)) * 180.0 / std::numbers::pi;
}

inline double PositionError(const Vec3f& a, const Vec3f& b) {
  const double dx = static_cast<double>(a.x) - b.x, dy = static_cast<double>(a.y) - b.y,
               dz = static_cast<double>(a.z) - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// float32 rounding slack of a coordinate of magnitude `m` (metres), Euclidean over 3 axes.
inline double FloatSlack(double m) { return 3.0 * std::ldexp(std::fabs(m) + 1.0, -23); }

}  // namespace edgephys::testing_util
