// Dissection output (Decoupled Edge Physics' algorithms 1-3) as plain structs: one entity's
// transform, parent, owner, flags and physics components (rigid body, colliders, joints, soft
// body).
// The client SDK spawns entities from it (client/client.h: SpawnDesc is EntitySpec); PhyS tests
// and scenes build worlds from it; protocol/container_builder.h serialises it to the
// schema::Container flatbuffer (schema/container.fbs).
//
// This header needs neither FlatBuffers nor the generated schema headers. The two enum types
// of the schema (ColliderShape, JointKind) are declared here opaquely, with their underlying
// type, so that a spec field is the schema's own type (code that includes the generated header
// assigns schema::ColliderShape::Sphere directly); code that does not names the values with the
// constants below. container_builder.cc checks that every constant equals the schema's value.
//
// Thread-safety: values. Units: metres, kilograms, seconds, radians, room frame.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "protocol/types.h"

namespace edgephys {

namespace schema {
enum class ColliderShape : uint8_t;  // defined in edgephys/schema/container_generated.h
enum class JointKind : uint8_t;      // defined in edgephys/schema/container_generated.h
}  // namespace schema

// schema::ColliderShape values (schema/container.fbs).
namespace collider_shape {
inline constexpr schema::ColliderShape kBox{0};
inline constexpr schema::ColliderShape kSphere{1};
inline constexpr schema::ColliderShape kCapsule{2};
inline constexpr schema::ColliderShape kCylinder{3};
inline constexpr schema::ColliderShape kConvexHull{4};
inline constexpr schema::ColliderShape kTriangleMesh{5};
}  // namespace collider_shape

// schema::JointKind values (schema/container.fbs).
namespace joint_kind {
inline constexpr schema::JointKind kFixed{0};
inline constexpr schema::JointKind kHinge{1};
inline constexpr schema::JointKind kSpring{2};
}  // namespace joint_kind

// schema::EntityFlags bits (schema/container.fbs) for EntitySpec::flags and
// RemoteEntity::flags; see the schema for what each one does.
namespace entity_flags {
inline constexpr uint32_t kPersistent = 1u << 0;
inline constexpr uint32_t kKinematic = 1u << 1;
inline constexpr uint32_t kInteractable = 1u << 2;
inline constexpr uint32_t kAvatar = 1u << 3;
inline constexpr uint32_t kHand = 1u << 4;
inline constexpr uint32_t kOffloaded = 1u << 5;
inline constexpr uint32_t kReportContacts = 1u << 6;
}  // namespace entity_flags

struct ColliderSpec {
  schema::ColliderShape shape = collider_shape::kBox;
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
  schema::JointKind kind = joint_kind::kFixed;
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
  uint32_t flags = 0;      // entity_flags bits (schema::EntityFlags)
  std::string name;
  std::optional<RigidBodySpec> rigid_body;
  std::vector<ColliderSpec> colliders;
  std::vector<JointSpec> joints;
  std::optional<SoftBodySpec> soft_body;
  // When its owner leaves (schema::OwnerLeave): 0 Default (Persistent: stay, else despawn),
  // 1 Stay (the room's, at rest), 2 PhyS (PhyS simulates a dynamic body on), 3 Despawn.
  uint8_t on_owner_leave = 0;
};

}  // namespace edgephys
