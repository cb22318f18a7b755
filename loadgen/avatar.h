// The avatar a ccu-style bot publishes: a kinematic head (Avatar) at standing height and two
// kinematic hands (Hand) with trigger spheres, the hands moving on smooth per-bot paths around
// the bot's home. Shared by the ccu and isolation scenarios so both load the relay alike.
#pragma once

#include <cstdint>

#include "client/client.h"
#include "protocol/types.h"

namespace edgephys::loadgen {

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
