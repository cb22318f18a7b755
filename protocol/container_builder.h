// Dissection output (the paper's algorithms 1-3): a plain-struct description of one entity —
// transform, parent, owner, flags and its physics components (rigid body, colliders, joints,
// soft body) — and its serializer to the schema::Container flatbuffer (schema/container.fbs).
// The client SDK spawns entities from it; PhyS tests and scenes build worlds from it.
//
// Thread-safety: pure functions over values. Cost: O(size of the spec); allocates the buffer.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "edgephys/schema/container_generated.h"
#include "protocol/state_codec.h"

namespace edgephys {

struct ColliderSpec {
  schema::ColliderShape shape = schema::ColliderShape::Box;
  Vec3f half_extents{0.5f, 0.5f, 0.5f};  // Box, Cylinder (m)
  float radius = 0.5f;                   // Sphere, Capsule (m)
  float height = 1.0f;                   // Capsule: between cap centres (m)
  Vec3f local_position;
  Quatf local_rotation;
  std::vector<float> vertices;           // x,y,z triples
  std::vector<uint32_t> indices;         // TriangleMesh
  bool is_trigger = false;
};

struct RigidBodySpec {
  float mass = 1.0f;  // kg
  float linear_damping = 0.0f;
  float angular_damping = 0.0f;
  float friction = 0.5f;
  float restitution = 0.0f;
  bool kinematic = false;
  bool use_gravity = true;
  Vec3f linear_velocity;
  Vec3f angular_velocity;
};

struct JointSpec {
  schema::JointKind kind = schema::JointKind::Fixed;
  uint32_t connected_entity = 0;
  Vec3f anchor;
  Vec3f axis{0.0f, 0.0f, 1.0f};
  float stiffness = 0.0f;
  float damping = 0.0f;
};

struct SoftBodySpec {
  std::vector<float> particles;  // x,y,z triples, room frame
  std::vector<float> masses;     // one per particle
  std::vector<uint32_t> springs; // index pairs
  float stiffness = 0.0f;        // N/m
  float damping = 0.0f;          // [0, 1]
};

// Member order is part of the interface: designated initialisers name the transform first,
// e.g. SpawnDesc{.position = {0, 1, 0}, .flags = ...} (client/client.h: SpawnDesc is this type).
struct EntitySpec {
  uint32_t id = 0;
  uint32_t owner = 0;  // player id; 0: the room (PhyS / orphaned)
  Vec3f position;      // metres, room frame
  Quatf rotation;      // unit quaternion
  Vec3f scale{1.0f, 1.0f, 1.0f};
  uint32_t parent_id = 0;  // 0: none
  uint32_t flags = 0;      // schema::EntityFlags bits
  std::string name;
  std::optional<RigidBodySpec> rigid_body;
  std::vector<ColliderSpec> colliders;
  std::vector<JointSpec> joints;
  std::optional<SoftBodySpec> soft_body;
};

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

}  // namespace edgephys
