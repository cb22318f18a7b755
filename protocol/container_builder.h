// Serialiser of the dissection output (EntitySpec, protocol/entity_spec.h: the plain structs
// for one entity's transform, parent, owner, flags and physics components) to the
// schema::Container flatbuffer (schema/container.fbs), plus convenience specs.
// The client SDK spawns entities from it; PhyS tests and scenes build worlds from it.
//
// Thread-safety: pure functions over values. Cost: O(size of the spec); allocates the buffer.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "edgephys/schema/container_generated.h"
#include "protocol/entity_spec.h"
#include "protocol/state_codec.h"

namespace edgephys {

// Serialises `spec` into a finished Container flatbuffer (file identifier "EPCT").
std::vector<uint8_t> BuildContainer(const EntitySpec& spec);
// Adds `spec` as a Container table to `fbb` (e.g. inside a Spawn message); not finished.
flatbuffers::Offset<schema::Container> AddContainer(flatbuffers::FlatBufferBuilder& fbb,
                                                    const EntitySpec& spec);

// The root Container of a buffer produced by BuildContainer (not verified; trusted input).
inline const schema::Container& AsContainer(const std::vector<uint8_t>& buffer) {
  return *schema::GetContainer(buffer.data());
}

// Convenience specs.
ColliderSpec BoxCollider(Vec3f half_extents);
ColliderSpec SphereCollider(float radius);
EntitySpec StaticBox(uint32_t id, Vec3f position, Vec3f half_extents, Quatf rotation = {});
EntitySpec DynamicBox(uint32_t id, Vec3f position, Vec3f half_extents, float mass);
EntitySpec DynamicSphere(uint32_t id, Vec3f position, float radius, float mass);
// A hand's grab zone: a kinematic, massless body whose one collider is a trigger sphere of
// `radius` (flags and owner are the caller's to set).
EntitySpec TriggerHand(uint32_t id, Vec3f position, float radius);

}  // namespace edgephys
