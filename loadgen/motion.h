// Deterministic smooth motion of what the load generator's clients move: benchmark objects
// (Motion) and the avatars of ccu-style bots (SpawnAvatar, AvatarHandPosition).
//
// Motion: the sender's truth, known exactly at any instant so receivers' errors can be measured
// against it. Each entity follows a Lissajous-like closed path around its own centre whose speed
// stays close to `speed_mps`, and spins at `spin_dps` about an axis that itself drifts slowly.
// Phases and frequencies come from `seed` and the entity index, so runs are reproducible and
// different seeds give different motions.
#pragma once

#include <cstdint>

#include "protocol/state_codec.h"
#include "protocol/types.h"

namespace edgephys {
class Client;
}  // namespace edgephys

namespace edgephys::loadgen {

// Echoed under --json "options" (relay-compare, interp-sweep, codec-sweep) under these names.
struct MotionParams {
  double speed_mps = 1.5;
  double spin_dps = 90;
  uint64_t seed = 1;
};

class Motion {
 public:
  Motion(const MotionParams& params, uint32_t index);
  // The pose at time `t` (seconds).
  EntityState At(double t) const;

 private:
  double cx_, cy_, cz_;            // centre
  double ax_, ay_, az_;            // amplitudes
  double wx_, wy_, wz_;            // angular frequencies
  double px_, py_, pz_;            // phases
  double spin_rad_s_;
  double axis_phase_, axis_rate_;  // slow drift of the spin axis
};

// The avatar a ccu-style bot publishes: a kinematic head (Avatar) at standing height and two
// kinematic hands (Hand) with trigger spheres, the hands moving on smooth per-bot paths around
// the bot's home. Shared by the ccu and isolation scenarios so both load the relay alike.
struct AvatarIds {
  uint32_t head = 0;
  uint32_t left = 0;
  uint32_t right = 0;
};

// Where bot `index`'s hand on `side` (-1 left, +1 right) is at time `t` (s): within ~0.45 m of
// `home`, at about 1.1 m height.
Vec3f AvatarHandPosition(const Vec3f& home, uint32_t index, double t, float side);

// Spawns the head and both hands through `client` (joined) at time `now`; false (ids partly
// set) if the SDK refused a spawn.
bool SpawnAvatar(Client& client, const Vec3f& home, uint32_t index, double now, AvatarIds* ids);

}  // namespace edgephys::loadgen
