// Velocities as state format 12 carries them (docs/protocol.md §5g), and the receiver model the
// relay's send decisions rely on: how a receiver shows a state with its velocity after it
// (ExtrapolateState, dead reckoning) and between two states (HermitePosition). Both ends use
// these functions, so what the relay bounds is what a receiver displays.
//
// Thread-safety: pure functions over values. Cost O(1), no allocation.
#pragma once

#include <array>
#include <cstdint>

#include "protocol/state_codec.h"

namespace edgephys {

inline constexpr double kLinearVelocityStep = 1.0 / 256;   // m/s per index
inline constexpr double kAngularVelocityStep = 1.0 / 256;  // rad/s per index
inline constexpr int32_t kMaxVelocityIndex = 1 << 14;      // |index| <= this: 64 m/s, 64 rad/s
inline constexpr double kVelocityExtrapolationLimitS = 1.0;

// A velocity on format 12's lattice.
struct QuantizedVelocity {
  std::array<int32_t, 3> linear{};
  std::array<int32_t, 3> angular{};
  bool moving() const {
    for (int a = 0; a < 3; ++a) {
      if (linear[a] != 0 || angular[a] != 0) return true;
    }
    return false;
  }
  friend bool operator==(const QuantizedVelocity&, const QuantizedVelocity&) = default;
};
// Rounds to the lattice, clamping to +-kMaxVelocityIndex; a non-finite component becomes 0.
QuantizedVelocity QuantizeVelocity(const EntityVelocity& v);
EntityVelocity DequantizeVelocity(const QuantizedVelocity& q);
// Where a receiver shows a state `dt_s` seconds after its time: position + linear * t and
// rotation turned by angular * t (world frame), t = clamp(dt_s, 0, kVelocityExtrapolationLimitS).
EntityState ExtrapolateState(const EntityState& state, const EntityVelocity& velocity, double dt_s);
// The cubic Hermite position between p0 (velocity v0) and p1 (v1), `h_s` seconds apart, at
// tau in [0, 1]: what a receiver interpolating with the sent velocities as tangents shows.
Vec3f HermitePosition(const Vec3f& p0, const Vec3f& v0, const Vec3f& p1, const Vec3f& v1,
                      double h_s, double tau);

}  // namespace edgephys
