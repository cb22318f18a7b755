// Deterministic smooth motion for benchmark entities: the sender's truth, known exactly at any
// instant so receivers' errors can be measured against it.
//
// Each entity follows a Lissajous-like closed path around its own centre whose speed stays
// close to `speed_mps`, and spins at `spin_dps` about an axis that itself drifts slowly. Phases
// and frequencies come from `seed` and the entity index, so runs are reproducible and
// different seeds give different motions.
#pragma once

#include <cstdint>

#include "protocol/state_codec.h"

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

}  // namespace edgephys::loadgen
