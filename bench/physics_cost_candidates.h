// The candidate PhysicsConfig settings that bench/physics_cost_report measures (--only NAME),
// each as step time against the accuracy suite. Every candidate starts from either PhyS's old
// defaults (the first sweep) or its current defaults (NewWith) and changes what its name says.
//
// Thread-safety: pure functions. Cost: Candidates() builds a small vector.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "physics_backend/physics_world.h"

namespace edgephys::physics {

struct Candidate {
  std::string name;
  std::function<void(PhysicsConfig&)> apply;  // sets the whole config (not a delta)
};

// Every candidate, in report order.
std::vector<Candidate> Candidates();

}  // namespace edgephys::physics
