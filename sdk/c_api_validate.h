// Argument checks of the C API (include/edgephys/edgephys.h): every float finite, every
// count within its documented bound, every pointer present where a count needs it, every enum
// in range; and the conversion of a checked edgephys_spawn_desc to the C++ EntitySpec.
//
// Thread-safety: pure functions. Cost: O(size of the description).
#pragma once

#include <string>

#include "edgephys/edgephys.h"
#include "protocol/container_builder.h"
#include "protocol/status.h"

namespace edgephys::capi {

bool Finite(float v);
bool FiniteVec(const edgephys_vec3& v);
// Finite and unit length within 1e-3 (what the relay accepts).
bool UnitQuat(const edgephys_quat& q);
// Finite position within +-1e6 m and a unit rotation.
Status CheckTransform(const edgephys_transform& t, const char* what);

// Checks `desc` (struct_size, every field and component) and fills `*spec` from it.
Status ToEntitySpec(const edgephys_spawn_desc& desc, EntitySpec* spec);

}  // namespace edgephys::capi
