// The container builder lives in protocol/ (the client SDK uses it for dissection); these
// names keep PhyS code and tests reading as before.
#pragma once

#include "protocol/container_builder.h"

namespace edgephys::physics {

using edgephys::AsContainer;
using edgephys::BoxCollider;
using edgephys::BuildContainer;
using edgephys::ColliderSpec;
using edgephys::DynamicBox;
using edgephys::DynamicSphere;
using edgephys::EntitySpec;
using edgephys::JointSpec;
using edgephys::RigidBodySpec;
using edgephys::SoftBodySpec;
using edgephys::StaticBox;

}  // namespace edgephys::physics
