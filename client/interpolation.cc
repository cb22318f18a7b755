#include "client/interpolation.h"

#include <algorithm>
#include <cmath>
#include <numbers>


namespace edgephys {
namespace {

using Eigen::Quaternionf;
using Eigen::Vector3f;

Quaternionf Negated(const Quaternionf& q) {
  Quaternionf r;
  r.coeffs() = -q.coeffs();
  return r;
}

Quaternionf AddQ(const Quaternionf& a, const Quaternionf& b) {
  Quaternionf r;
  r.coeffs() = a.coeffs() + b.coeffs();
  return r;
}

Quaternionf ScaleQ(const Quaternionf& a, float s) {
  Quaternionf r;
  r.coeffs() = a.coeffs() * s;
  return r;
}

// sin(x) / x, accurate near 0.
float SinOverX(float x) {
  if (std::fabs(x) < 1e-3f) return 1.0f - x * x / 6.0f;
  return std::sin(x) / x;
}

// Log of a unit quaternion, short way: (angle / 2) * axis.
Vector3f QuatLog(const Quaternionf& q_in) {
  const Quaternionf q = q_in.w() < 0 ? Negated(q_in) : q_in;
  const float n = q.vec().norm();
  const float half = std::atan2(n, q.w());
  if (n < 1e-12f) return Vector3f::Zero();
  return q.vec() * (half / n);
}

// Inverse of QuatLog: a unit quaternion.
Quaternionf QuatExp(const Vector3f& v) {
  const float half = v.norm();
  Quaternionf q;
  q.w() = std::cos(half);
  q.vec() = v * SinOverX(half);
  return q;
}

Pose PoseOf(const Snapshot& s) { return {s.position, s.rotation}; }

bool GapOk(double h, const SampleOptions& options) {
  return h >= options.min_velocity_gap_s && h <= options.max_gap_s;
}

// Indices of the snapshots used to estimate a derivative at index i: the parabola through i and
// its neighbours (centred if possible, else one-sided), a line through two, or i alone.
struct Stencil {
  size_t idx[3] = {0, 0, 0};
  int count = 0;
};

Stencil PickStencil(const SnapshotBuffer& b, size_t i, const SampleOptions& options) {
  const size_t n = b.size();
  auto ok = [&](size_t a, size_t c) {
    return GapOk(b[c].sender_time_s - b[a].sender_time_s, options);
  };
  const bool prev = i > 0 && ok(i - 1, i);
  const bool next = i + 1 < n && ok(i, i + 1);
  if (prev && next) return {{i - 1, i, i + 1}, 3};
  if (next) {
    if (i + 2 < n && ok(i + 1, i + 2)) return {{i, i + 1, i + 2}, 3};
    return {{i, i + 1, 0}, 2};
  }
  if (prev) {
    if (i >= 2 && ok(i - 2, i - 1)) return {{i - 2, i - 1, i}, 3};
    return {{i - 1, i, 0}, 2};
  }
  return {{i, 0, 0}, 1};
}

// Derivative at b[i]'s time of the polynomial through the stencil's (time, value(j)) points.
template <typename ValueFn>
Vector3f DerivativeAt(const SnapshotBuffer& b, size_t i, const Stencil& st, ValueFn value) {
  const double ti = b[i].sender_time_s;
  if (st.count == 2) {
    const double h = b[st.idx[1]].sender_time_s - b[st.idx[0]].sender_time_s;
    return (value(st.idx[1]) - value(st.idx[0])) / static_cast<float>(h);
  }
  if (st.count < 3) return Vector3f::Zero();
  // Lagrange basis derivatives, times relative to ti.
  const double t0 = b[st.idx[0]].sender_time_s - ti;
  const double t1 = b[st.idx[1]].sender_time_s - ti;
  const double t2 = b[st.idx[2]].sender_time_s - ti;
  const double w0 = (-t1 - t2) / ((t0 - t1) * (t0 - t2));
  const double w1 = (-t0 - t2) / ((t1 - t0) * (t1 - t2));
  const double w2 = (-t0 - t1) / ((t2 - t0) * (t2 - t1));
  return value(st.idx[0]) * static_cast<float>(w0) + value(st.idx[1]) * static_cast<float>(w1) +
         value(st.idx[2]) * static_cast<float>(w2);
}

// Linear velocity (m/s, world) at b[i]: its own if sent, else estimated from neighbours.
Vector3f LinearVelocityAt(const SnapshotBuffer& b, size_t i, const SampleOptions& options) {
  if (b[i].has_linear_velocity) return ToEigen(b[i].linear_velocity);
  return DerivativeAt(b, i, PickStencil(b, i, options),
                      [&](size_t j) { return ToEigen(b[j].position); });
}

// Rate of the rotation's log in b[i]'s body frame: half the body angular velocity (rad/s), so
// that q(t) ~= q_i * QuatExp(rate * (t - t_i)).
Vector3f LogRateAt(const SnapshotBuffer& b, size_t i, const SampleOptions& options) {
  const Quaternionf qi = ToEigen(b[i].rotation);
  if (b[i].has_angular_velocity) {
    return 0.5f * (qi.conjugate() * ToEigen(b[i].angular_velocity));
  }
  const Quaternionf qi_inv = qi.conjugate();
  return DerivativeAt(b, i, PickStencil(b, i, options),
                      [&](size_t j) { return QuatLog(qi_inv * ToEigen(b[j].rotation)); });
}

Pose LerpSlerp(const Pose& a, const Pose& b, float t) {
  const Vector3f pa = ToEigen(a.position);
  const Vector3f p = pa + t * (ToEigen(b.position) - pa);
  return {FromEigen(p), FromEigen(Slerp(ToEigen(a.rotation), ToEigen(b.rotation), t))};
}

// Cubic Hermite position and squad rotation on the segment b[i0] -> b[i0 + 1].
Pose HermiteSegment(const SnapshotBuffer& b, size_t i0, float tau, const SampleOptions& options) {
  const size_t i1 = i0 + 1;
  const float h = static_cast<float>(b[i1].sender_time_s - b[i0].sender_time_s);
  const Vector3f p0 = ToEigen(b[i0].position);
  const Vector3f p1 = ToEigen(b[i1].position);
  const Vector3f m0 = LinearVelocityAt(b, i0, options) * h;
  const Vector3f m1 = LinearVelocityAt(b, i1, options) * h;
  const float t2 = tau * tau, t3 = t2 * tau;
  const Vector3f p = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + tau) * m0 +
                     (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1;

  // Squad with control points chosen so that the curve's log-rate at each end matches the
  // estimated angular rate (the usual central-difference control points for uniform spacing).
  const Quaternionf q0 = ToEigen(b[i0].rotation);
  Quaternionf q1 = ToEigen(b[i1].rotation);
  if (q0.dot(q1) < 0) q1 = Negated(q1);
  const Vector3f l = QuatLog(q0.conjugate() * q1);
  const Vector3f r0 = LogRateAt(b, i0, options) * h;
  const Vector3f r1 = LogRateAt(b, i1, options) * h;
  const Quaternionf s0 = q0 * QuatExp(0.5f * (r0 - l));
  const Quaternionf s1 = q1 * QuatExp(0.5f * (l - r1));
  const Quaternionf q = Slerp(Slerp(q0, q1, tau), Slerp(s0, s1, tau), 2 * tau * (1 - tau));
  return {FromEigen(p), FromEigen(q)};
}

Pose Extrapolate(const SnapshotBuffer& b, double ahead_s, Interpolator method,
                 const SampleOptions& options) {
  const size_t n = b.size();
  const Snapshot& last = b.newest();
  const double e = std::min(ahead_s, options.max_extrapolation_s);
  if (method == Interpolator::kNone || !(e > 0)) return PoseOf(last);

  const bool has_velocity = last.has_linear_velocity || last.has_angular_velocity;
  if (method == Interpolator::kHermite || has_velocity) {
    const float ef = static_cast<float>(e);
    const Vector3f p = ToEigen(last.position) + LinearVelocityAt(b, n - 1, options) * ef;
    const Quaternionf q =
        (ToEigen(last.rotation) * QuatExp(LogRateAt(b, n - 1, options) * ef)).normalized();
    return {FromEigen(p), FromEigen(q)};
  }
  if (n < 2) return PoseOf(last);
  const Snapshot& prev = b[n - 2];
  const double h = last.sender_time_s - prev.sender_time_s;
  if (!GapOk(h, options)) return PoseOf(last);
  const float tau = static_cast<float>(1.0 + e / h);
  if (method == Interpolator::kLerpSlerp) return LerpSlerp(PoseOf(prev), PoseOf(last), tau);
  // Both dual-quaternion methods continue the last segment's screw.
  return DualQuaternion::Sclerp(DualQuaternion::FromPose(PoseOf(prev)),
                                DualQuaternion::FromPose(PoseOf(last)), tau)
      .ToPose();
}

}  // namespace

SnapshotBufferConfig CapPlayoutDelay(const SnapshotBufferConfig& config, double max_delay_s) {
  SnapshotBufferConfig capped = config;
  if (!(max_delay_s > 0) || !std::isfinite(max_delay_s)) return capped;
  capped.min_delay_s = std::min(capped.min_delay_s, max_delay_s);
  capped.max_delay_s = std::min(capped.max_delay_s, max_delay_s);
  return capped;
}

const char* InterpolatorName(Interpolator method) {
  switch (method) {
    case Interpolator::kLerpSlerp:
      return "lerp_slerp";
    case Interpolator::kDualQuatDlb:
      return "dq_dlb";
    case Interpolator::kDualQuatSclerp:
      return "dq_sclerp";
    case Interpolator::kHermite:
      return "hermite";
    case Interpolator::kNone:
      return "none";
  }
  return "unknown";
}

Quaternionf Slerp(const Quaternionf& a, const Quaternionf& b, float t) {
  return (a * QuatExp(t * QuatLog(a.conjugate() * b))).normalized();
}

// --- DualQuaternion ---

DualQuaternion DualQuaternion::FromRigid(const Quaternionf& rotation, const Vector3f& translation) {
  const Quaternionf r = rotation.normalized();
  const Quaternionf t(0, translation.x(), translation.y(), translation.z());
  return {r, ScaleQ(t * r, 0.5f)};
}

DualQuaternion DualQuaternion::FromPose(const Pose& pose) {
  return FromRigid(ToEigen(pose.rotation), ToEigen(pose.position));
}

Vector3f DualQuaternion::translation() const {
  return (dual_ * real_.conjugate()).vec() * (2.0f / real_.squaredNorm());
}

Pose DualQuaternion::ToPose() const { return {FromEigen(translation()), FromEigen(rotation())}; }

Vector3f DualQuaternion::TransformPoint(const Vector3f& p) const {
  return rotation() * p + translation();
}

DualQuaternion DualQuaternion::operator*(const DualQuaternion& o) const {
  return {real_ * o.real_, AddQ(real_ * o.dual_, dual_ * o.real_)};
}

DualQuaternion DualQuaternion::operator+(const DualQuaternion& o) const {
  return {AddQ(real_, o.real_), AddQ(dual_, o.dual_)};
}

DualQuaternion DualQuaternion::operator*(float scale) const {
  return {ScaleQ(real_, scale), ScaleQ(dual_, scale)};
}

DualQuaternion DualQuaternion::Conjugate() const { return {real_.conjugate(), dual_.conjugate()}; }

DualQuaternion DualQuaternion::Normalized() const {
  const float n = real_.norm();
  if (!(n > 0)) return {};
  const Quaternionf r = ScaleQ(real_, 1.0f / n);
  Quaternionf d = ScaleQ(dual_, 1.0f / n);
  d.coeffs() -= r.coeffs() * r.coeffs().dot(d.coeffs());
  return {r, d};
}

DualQuaternion DualQuaternion::Pow(float tau) const {
  Quaternionf r = real_.normalized();
  if (r.w() < 0) r = Negated(r);
  const Vector3f t = translation();
  const float s = r.vec().norm();
  const float half = std::atan2(s, r.w());  // half the rotation angle, in [0, pi/2]
  Vector3f axis;
  if (s > 1e-12f) {
    axis = r.vec() / s;
  } else if (t.squaredNorm() > 0) {
    axis = t.normalized();  // no rotation: any axis gives the same result
  } else {
    axis = Vector3f::UnitX();
  }
  // Screw decomposition: t = t_perp + pitch * axis, t_perp = (I - R) c for a point c on the
  // axis. Raising to tau rotates by tau * angle about the same axis and scales the pitch; the
  // translation becomes (I - R_tau) c + tau * pitch * axis, written without c (stable as the
  // angle goes to 0) as a * t_perp + b * (axis x t_perp).
  const float pitch = t.dot(axis);
  const Vector3f t_perp = t - pitch * axis;
  const float ratio = tau * SinOverX(tau * half) / SinOverX(half);  // sin(tau h) / sin(h)
  const float a = ratio * std::cos((1 - tau) * half);
  const float b = -ratio * std::sin((1 - tau) * half);
  const Vector3f t_tau = a * t_perp + b * axis.cross(t_perp) + (tau * pitch) * axis;
  Quaternionf r_tau;
  r_tau.w() = std::cos(tau * half);
  r_tau.vec() = axis * std::sin(tau * half);
  return FromRigid(r_tau, t_tau);
}

DualQuaternion DualQuaternion::Dlb(const DualQuaternion& a, const DualQuaternion& b, float t) {
  const DualQuaternion b_near = a.real_.dot(b.real_) < 0 ? -b : b;
  return (a * (1 - t) + b_near * t).Normalized();
}

DualQuaternion DualQuaternion::Sclerp(const DualQuaternion& a, const DualQuaternion& b, float t) {
  return a * (a.Conjugate() * b).Pow(t);
}

// --- Sampling ---

Pose Sample(const SnapshotBuffer& buffer, double render_time_s, Interpolator method,
            const SampleOptions& options) {
  const size_t n = buffer.size();
  if (n == 0) return {};
  if (!(render_time_s > buffer.oldest().sender_time_s)) return PoseOf(buffer.oldest());
  if (render_time_s >= buffer.newest().sender_time_s) {
    return Extrapolate(buffer, render_time_s - buffer.newest().sender_time_s, method, options);
  }
  const size_t i1 = buffer.UpperBound(render_time_s);  // in [1, n - 1]
  const size_t i0 = i1 - 1;
  const Snapshot& s0 = buffer[i0];
  const Snapshot& s1 = buffer[i1];
  const double h = s1.sender_time_s - s0.sender_time_s;
  const float tau =
      static_cast<float>(std::clamp((render_time_s - s0.sender_time_s) / h, 0.0, 1.0));
  switch (method) {
    case Interpolator::kNone:
      return PoseOf(s0);
    case Interpolator::kLerpSlerp:
      return LerpSlerp(PoseOf(s0), PoseOf(s1), tau);
    case Interpolator::kDualQuatDlb:
      return DualQuaternion::Dlb(DualQuaternion::FromPose(PoseOf(s0)),
                                 DualQuaternion::FromPose(PoseOf(s1)), tau)
          .ToPose();
    case Interpolator::kDualQuatSclerp:
      return DualQuaternion::Sclerp(DualQuaternion::FromPose(PoseOf(s0)),
                                    DualQuaternion::FromPose(PoseOf(s1)), tau)
          .ToPose();
    case Interpolator::kHermite:
      if (h > options.max_gap_s) return LerpSlerp(PoseOf(s0), PoseOf(s1), tau);
      return HermiteSegment(buffer, i0, tau, options);
  }
  return PoseOf(s0);
}

PoseError Compare(const Pose& a, const Pose& b) {
  const Eigen::Vector3d pa(a.position.x, a.position.y, a.position.z);
  const Eigen::Vector3d pb(b.position.x, b.position.y, b.position.z);
  const Eigen::Quaterniond qa =
      Eigen::Quaterniond(a.rotation.w, a.rotation.x, a.rotation.y, a.rotation.z).normalized();
  const Eigen::Quaterniond qb =
      Eigen::Quaterniond(b.rotation.w, b.rotation.x, b.rotation.y, b.rotation.z).normalized();
  const Eigen::Quaterniond rel = qa.conjugate() * qb;
  const double angle = 2.0 * std::atan2(rel.vec().norm(), std::fabs(rel.w()));
  return {(pa - pb).norm(), angle * 180.0 / std::numbers::pi};
}

}  // namespace edgephys
