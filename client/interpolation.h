// Pose interpolation between buffered snapshots (client/snapshot_buffer.h). Decoupled Edge
// Physics smooths received transforms with a dual-quaternion interpolator; this file offers it
// (both the
// normalised linear blend, DLB, and screw linear interpolation, ScLERP) beside lerp+slerp, cubic
// Hermite, and hold-last, so that their accuracy can be measured side by side
// (docs/benchmarks.md, "Interpolation").
//
//   Pose pose = Sample(buffer, buffer.RenderTime(now), Interpolator::kDualQuatSclerp);
//
// Semantics of Sample(buffer, t, method):
//   * empty buffer: the identity pose (origin, no rotation);
//   * t at or before the oldest snapshot: the oldest pose (no extrapolation into the past);
//   * t between two snapshots: interpolated by `method`;
//   * t after the newest: extrapolated for at most `max_extrapolation_s` (default 100 ms), then
//     held at the pose extrapolated to that limit (continuous, never runs away). The motion
//     model: the snapshot's own velocities when it carries them; otherwise kDualQuat* continue
//     the screw of the last segment, kLerpSlerp continues its line and rotation rate, kHermite
//     uses the velocity estimated at the newest snapshot. kNone holds the newest;
//   * segments longer than `max_gap_s` (default 1 s, e.g. after a stall) are never used to
//     estimate velocities, and kHermite interpolates them linearly, so a huge gap cannot make the
//     curve overshoot.
// Quaternions q and -q are the same rotation; every method interpolates the short way.
//
// Accuracy (see client/interpolation_test.cc for the measured numbers):
//   kLerpSlerp      exact for constant linear velocity and for rotation about the body origin
//                   with constant angular velocity; on a circle of radius R with angle step
//                   theta per segment the position error is up to the sagitta R*theta^2/8.
//   kDualQuatDlb    exact for constant-velocity lines; close to ScLERP elsewhere (normalised
//                   blend: the rate is not uniform, error grows ~ theta^3).
//   kDualQuatSclerp exact for any uniform screw motion (constant twist), which includes lines,
//                   rotation about any fixed axis and helices.
//   kHermite        cubic Hermite in position (velocities from the snapshots, else the
//                   derivative of the parabola through the neighbours, exact for constant
//                   acceleration) and a Hermite-style squad in rotation with matching angular
//                   rates (exact for constant angular velocity).
//   kNone           step function: the latest snapshot at or before t.
//
// Thread-safety: all functions are pure (the buffer is only read); call them from any thread as
// long as nobody modifies the buffer concurrently.
// Cost: Sample() is O(log capacity) to find the segment plus a constant number of quaternion
// products and trig calls (timings: bench/interpolation_bench.cc). No allocation.
#pragma once

#include <Eigen/Geometry>

#include "client/snapshot_buffer.h"
#include "protocol/state_codec.h"

namespace edgephys {

enum class Interpolator {
  kLerpSlerp,       // linear position + spherical linear rotation
  kDualQuatDlb,     // dual-quaternion linear blending, normalised
  kDualQuatSclerp,  // dual-quaternion screw linear interpolation
  kHermite,         // cubic Hermite position + squad rotation
  kNone,            // hold the last snapshot at or before the render time
};

// Name for logs and benchmark labels ("lerp_slerp", "dq_dlb", "dq_sclerp", "hermite", "none").
const char* InterpolatorName(Interpolator method);

// `config` with its playout delay held to at most `max_delay_s` (seconds; an application's
// latency limit: edgephys_client_set_max_playout_delay). Both delay bounds are lowered to it,
// so the adaptive delay never exceeds it. 0, negative or non-finite: `config` unchanged. The
// price is accuracy when the delay falls below the interval between an entity's states: the
// render time runs ahead of the newest state and the sampler extrapolates for up to
// SampleOptions::max_extrapolation_s. O(1).
SnapshotBufferConfig CapPlayoutDelay(const SnapshotBufferConfig& config, double max_delay_s);

struct Pose {
  Vec3f position;  // metres
  Quatf rotation;  // unit quaternion
};

struct SampleOptions {
  double max_extrapolation_s = 0.100;  // extrapolate at most this far past the newest snapshot
  double max_gap_s = 1.0;              // longer segments: no velocity estimate across them
  double min_velocity_gap_s = 1e-3;    // shorter segments: too noisy to estimate velocity from
};

// The pose of the buffered entity at sender time `render_time_s` (see the file comment).
Pose Sample(const SnapshotBuffer& buffer, double render_time_s, Interpolator method,
            const SampleOptions& options = {});

// Difference of two poses: Euclidean position distance (m) and the angle of a^-1 * b in degrees
// in [0, 180] (q and -q compare equal).
struct PoseError {
  double pos_m = 0;
  double rot_deg = 0;
};
PoseError Compare(const Pose& a, const Pose& b);

// Unit dual quaternion sigma = r + eps * d for a rigid transform x -> R x + t, with
// r the rotation and d = 0.5 * t * r (t as a pure quaternion). Products compose like the
// transforms they represent: (a * b) applies b first. A value type; float precision.
class DualQuaternion {
 public:
  DualQuaternion() : real_(Eigen::Quaternionf::Identity()), dual_(0, 0, 0, 0) {}
  DualQuaternion(const Eigen::Quaternionf& real, const Eigen::Quaternionf& dual)
      : real_(real), dual_(dual) {}

  // From a rotation (need not be normalised exactly; it is normalised) and a translation.
  static DualQuaternion FromRigid(const Eigen::Quaternionf& rotation,
                                  const Eigen::Vector3f& translation);
  static DualQuaternion FromPose(const Pose& pose);

  const Eigen::Quaternionf& real() const { return real_; }
  const Eigen::Quaternionf& dual() const { return dual_; }
  Eigen::Quaternionf rotation() const { return real_.normalized(); }
  // t = 2 * d * conj(r) / |r|^2 (vector part); valid for unnormalised blends too.
  Eigen::Vector3f translation() const;
  Pose ToPose() const;
  // Applies the transform to a point.
  Eigen::Vector3f TransformPoint(const Eigen::Vector3f& p) const;

  DualQuaternion operator*(const DualQuaternion& other) const;
  DualQuaternion operator+(const DualQuaternion& other) const;
  DualQuaternion operator*(float scale) const;
  DualQuaternion operator-() const { return *this * -1.0f; }
  // Quaternion conjugate of both parts: the inverse of a unit dual quaternion.
  DualQuaternion Conjugate() const;
  // Nearest unit dual quaternion: real part normalised, dual part made orthogonal to it.
  DualQuaternion Normalized() const;
  // sigma^tau for a unit dual quaternion along its screw axis (rotation by tau * angle about the
  // axis, translation by tau * pitch along it). Takes the short way (real part w >= 0). Stable as
  // the angle goes to 0 (pure translation). Any real tau, so tau > 1 extrapolates.
  DualQuaternion Pow(float tau) const;

  // Normalised (1 - t) * a + t * b, with b's sign chosen to be on a's hemisphere.
  static DualQuaternion Dlb(const DualQuaternion& a, const DualQuaternion& b, float t);
  // a * (conj(a) * b)^t: uniform screw motion from a (t = 0) to b (t = 1).
  static DualQuaternion Sclerp(const DualQuaternion& a, const DualQuaternion& b, float t);

 private:
  Eigen::Quaternionf real_;
  Eigen::Quaternionf dual_;
};

// Conversions between the wire types and Eigen.
inline Eigen::Vector3f ToEigen(const Vec3f& v) { return {v.x, v.y, v.z}; }
inline Eigen::Quaternionf ToEigen(const Quatf& q) { return {q.w, q.x, q.y, q.z}; }
inline Vec3f FromEigen(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }
inline Quatf FromEigen(const Eigen::Quaternionf& q) { return {q.x(), q.y(), q.z(), q.w()}; }

// Shortest-path spherical interpolation a -> b; t outside [0, 1] extrapolates at the same
// angular rate. Stable for nearly equal inputs.
Eigen::Quaternionf Slerp(const Eigen::Quaternionf& a, const Eigen::Quaternionf& b, float t);

}  // namespace edgephys
