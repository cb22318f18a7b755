#include "protocol/velocity.h"

#include <algorithm>
#include <cmath>

namespace edgephys {
namespace {

int32_t QuantizeVelocityComponent(float v, double step) {
  if (!std::isfinite(v)) return 0;
  const double x = std::round(static_cast<double>(v) / step);
  return static_cast<int32_t>(std::clamp<double>(x, -kMaxVelocityIndex, kMaxVelocityIndex));
}

}  // namespace

QuantizedVelocity QuantizeVelocity(const EntityVelocity& v) {
  QuantizedVelocity q;
  const float lin[3] = {v.linear.x, v.linear.y, v.linear.z};
  const float ang[3] = {v.angular.x, v.angular.y, v.angular.z};
  for (int a = 0; a < 3; ++a) {
    q.linear[a] = QuantizeVelocityComponent(lin[a], kLinearVelocityStep);
    q.angular[a] = QuantizeVelocityComponent(ang[a], kAngularVelocityStep);
  }
  return q;
}

EntityVelocity DequantizeVelocity(const QuantizedVelocity& q) {
  auto f = [](int32_t x, double step) { return static_cast<float>(x * step); };
  EntityVelocity v;
  v.linear = {f(q.linear[0], kLinearVelocityStep), f(q.linear[1], kLinearVelocityStep),
              f(q.linear[2], kLinearVelocityStep)};
  v.angular = {f(q.angular[0], kAngularVelocityStep), f(q.angular[1], kAngularVelocityStep),
               f(q.angular[2], kAngularVelocityStep)};
  return v;
}

EntityState ExtrapolateState(const EntityState& state, const EntityVelocity& velocity,
                             double dt_s) {
  const double t = std::clamp(std::isfinite(dt_s) ? dt_s : 0.0, 0.0, kVelocityExtrapolationLimitS);
  EntityState out = state;
  out.position.x = static_cast<float>(state.position.x + velocity.linear.x * t);
  out.position.y = static_cast<float>(state.position.y + velocity.linear.y * t);
  out.position.z = static_cast<float>(state.position.z + velocity.linear.z * t);
  const double wx = velocity.angular.x, wy = velocity.angular.y, wz = velocity.angular.z;
  const double w = std::sqrt(wx * wx + wy * wy + wz * wz);
  if (w * t > 1e-9) {
    // q' = exp(omega t / 2) * q (angular velocity in the world frame).
    const double half = 0.5 * w * t;
    const double sn = std::sin(half) / w, c = std::cos(half);
    const double ax = wx * sn, ay = wy * sn, az = wz * sn;
    const Quatf& q = state.rotation;
    double x = c * q.x + ax * q.w + ay * q.z - az * q.y;
    double y = c * q.y - ax * q.z + ay * q.w + az * q.x;
    double z = c * q.z + ax * q.y - ay * q.x + az * q.w;
    double qw = c * q.w - ax * q.x - ay * q.y - az * q.z;
    const double n = std::sqrt(x * x + y * y + z * z + qw * qw);
    if (n > 0) {
      x /= n, y /= n, z /= n, qw /= n;
    }
    out.rotation = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z),
                    static_cast<float>(qw)};
  }
  return out;
}

Vec3f HermitePosition(const Vec3f& p0, const Vec3f& v0, const Vec3f& p1, const Vec3f& v1,
                      double h_s, double tau) {
  const double t2 = tau * tau, t3 = t2 * tau;
  const double a = 2 * t3 - 3 * t2 + 1, b = (t3 - 2 * t2 + tau) * h_s, c = -2 * t3 + 3 * t2,
               d = (t3 - t2) * h_s;
  auto f = [&](float x0, float m0, float x1, float m1) {
    return static_cast<float>(a * x0 + b * m0 + c * x1 + d * m1);
  };
  return {f(p0.x, v0.x, p1.x, v1.x), f(p0.y, v0.y, p1.y, v1.y), f(p0.z, v0.z, p1.z, v1.z)};
}

}  // namespace edgephys
