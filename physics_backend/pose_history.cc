#include "physics_backend/pose_history.h"

#include <Eigen/Geometry>
#include <cmath>

namespace edgephys::physics {

void PoseHistory::Add(double time, const Vec3f& position, const Quatf& rotation) {
  if (!std::isfinite(time)) return;
  if (count_ > 0) {
    const double newest = At(0).t;
    if (time < newest) return;
    if (time == newest) {
      ring_[(next_ + kCapacity - 1) % kCapacity] = {time, position, rotation};
      return;
    }
  }
  ring_[next_] = {time, position, rotation};
  next_ = (next_ + 1) % kCapacity;
  if (count_ < kCapacity) ++count_;
}

bool PoseHistory::Newest(double* time, Vec3f* position, Quatf* rotation) const {
  if (count_ == 0) return false;
  const Sample& s = At(0);
  *time = s.t;
  *position = s.p;
  *rotation = s.q;
  return true;
}

bool PoseHistory::Estimate(double window_s, Vec3f* linear, Vec3f* angular) const {
  if (count_ == 0 || !(window_s > 0)) return false;
  const Sample& newest = At(0);
  size_t n = 0;
  while (n < count_ && newest.t - At(n).t <= window_s) ++n;
  if (n < 3 || newest.t - At(n - 1).t < window_s / 3) return false;

  // Rotation vectors relative to the newest rotation, in the world frame: for a constant
  // world-frame angular velocity w, q(t) q(tn)^-1 = exp(w (t - tn)), whose vector is w (t - tn).
  const Eigen::Quaterniond qn =
      Eigen::Quaterniond(newest.q.w, newest.q.x, newest.q.y, newest.q.z).normalized();
  double mean_t = 0;
  Eigen::Vector3d mean_p = Eigen::Vector3d::Zero(), mean_r = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, kCapacity> r;
  for (size_t i = 0; i < n; ++i) {
    const Sample& s = At(i);
    Eigen::Quaterniond d =
        Eigen::Quaterniond(s.q.w, s.q.x, s.q.y, s.q.z).normalized() * qn.conjugate();
    if (d.w() < 0) d.coeffs() = -d.coeffs();  // the shorter way round
    const Eigen::AngleAxisd aa(d);
    r[i] = aa.axis() * aa.angle();
    mean_t += s.t - newest.t;
    mean_p += Eigen::Vector3d(s.p.x, s.p.y, s.p.z);
    mean_r += r[i];
  }
  mean_t /= static_cast<double>(n);
  mean_p /= static_cast<double>(n);
  mean_r /= static_cast<double>(n);
  double stt = 0;
  Eigen::Vector3d stp = Eigen::Vector3d::Zero(), str = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Sample& s = At(i);
    const double dt = (s.t - newest.t) - mean_t;
    stt += dt * dt;
    stp += dt * (Eigen::Vector3d(s.p.x, s.p.y, s.p.z) - mean_p);
    str += dt * (r[i] - mean_r);
  }
  if (!(stt > 0)) return false;
  const Eigen::Vector3d v = stp / stt, w = str / stt;
  if (!v.allFinite() || !w.allFinite()) return false;
  *linear = {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
  *angular = {static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z())};
  return true;
}

}  // namespace edgephys::physics
