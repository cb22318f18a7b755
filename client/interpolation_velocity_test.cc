// Receivers of state format 12 show what the relay's send decisions model: Sample with the
// sent velocities extrapolates exactly as ExtrapolateState (dead reckoning) and interpolates
// exactly as HermitePosition (the interpolation check), so that the error bound the relay
// enforces is the one a receiver sees.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "client/interpolation.h"
#include "client/snapshot_buffer.h"
#include "protocol/delta_codec.h"

namespace edgephys {
namespace {

Snapshot Snap(double t, const EntityState& s, const EntityVelocity& v) {
  Snapshot out{.sender_time_s = t, .position = s.position, .rotation = s.rotation};
  out.has_linear_velocity = out.has_angular_velocity = true;
  out.linear_velocity = v.linear;
  out.angular_velocity = v.angular;
  return out;
}

Quatf Normalized(float x, float y, float z, float w) {
  const float n = std::sqrt(x * x + y * y + z * z + w * w);
  return {x / n, y / n, z / n, w / n};
}

TEST(VelocityDisplay, ExtrapolationMatchesTheRelaysModel) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-3, 3);
  SampleOptions options;
  options.max_extrapolation_s = kVelocityExtrapolationLimitS;
  for (int trial = 0; trial < 200; ++trial) {
    EntityState s;
    s.position = {u(rng), u(rng), u(rng)};
    s.rotation = Normalized(u(rng), u(rng), u(rng), u(rng));
    const EntityVelocity v{{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}};
    SnapshotBuffer b;
    ASSERT_EQ(b.Insert(Snap(10.0, s, v), 10.0), InsertResult::kInserted);
    for (double dt : {0.0, 0.05, 0.3, 0.99, 1.5, 4.0}) {
      const EntityState want = ExtrapolateState(s, v, dt);
      const Pose got = Sample(b, 10.0 + dt, Interpolator::kHermite, options);
      const PoseError e = Compare(got, {want.position, want.rotation});
      ASSERT_LT(e.pos_m, 2e-5) << trial << " " << dt;
      ASSERT_LT(e.rot_deg, 0.02) << trial << " " << dt;
    }
  }
}

TEST(VelocityDisplay, InterpolationMatchesTheRelaysHermiteCurve) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<float> u(-3, 3);
  for (int trial = 0; trial < 200; ++trial) {
    EntityState a, c;
    a.position = {u(rng), u(rng), u(rng)};
    c.position = {u(rng), u(rng), u(rng)};
    const EntityVelocity va{{u(rng), u(rng), u(rng)}, {}};
    const EntityVelocity vc{{u(rng), u(rng), u(rng)}, {}};
    const double h = 0.05 + 0.4 * (trial % 10) / 10.0;
    SnapshotBuffer b;
    ASSERT_EQ(b.Insert(Snap(20.0, a, va), 20.0), InsertResult::kInserted);
    ASSERT_EQ(b.Insert(Snap(20.0 + h, c, vc), 20.0 + h), InsertResult::kInserted);
    for (double tau : {0.1, 0.5, 0.9}) {
      const Vec3f want = HermitePosition(a.position, va.linear, c.position, vc.linear, h, tau);
      const Pose got = Sample(b, 20.0 + tau * h, Interpolator::kHermite);
      ASSERT_LT(Compare(got, {want, {}}).pos_m, 2e-5) << trial << " " << tau;
    }
  }
}

}  // namespace
}  // namespace edgephys
