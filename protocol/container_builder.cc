#include "protocol/container_builder.h"

#include <flatbuffers/flatbuffers.h>

#include <optional>
#include <utility>

namespace edgephys {
namespace {

// protocol/entity_spec.h names the schema's values without the generated header.
static_assert(collider_shape::kBox == schema::ColliderShape::Box);
static_assert(collider_shape::kSphere == schema::ColliderShape::Sphere);
static_assert(collider_shape::kCapsule == schema::ColliderShape::Capsule);
static_assert(collider_shape::kCylinder == schema::ColliderShape::Cylinder);
static_assert(collider_shape::kConvexHull == schema::ColliderShape::ConvexHull);
static_assert(collider_shape::kTriangleMesh == schema::ColliderShape::TriangleMesh);
static_assert(schema::ColliderShape::MAX == schema::ColliderShape::TriangleMesh);
static_assert(joint_kind::kFixed == schema::JointKind::Fixed);
static_assert(joint_kind::kHinge == schema::JointKind::Hinge);
static_assert(joint_kind::kSpring == schema::JointKind::Spring);
static_assert(schema::JointKind::MAX == schema::JointKind::Spring);
constexpr uint32_t Bit(schema::EntityFlags f) { return static_cast<uint32_t>(f); }
static_assert(entity_flags::kPersistent == Bit(schema::EntityFlags::Persistent));
static_assert(entity_flags::kKinematic == Bit(schema::EntityFlags::Kinematic));
static_assert(entity_flags::kInteractable == Bit(schema::EntityFlags::Interactable));
static_assert(entity_flags::kAvatar == Bit(schema::EntityFlags::Avatar));
static_assert(entity_flags::kHand == Bit(schema::EntityFlags::Hand));
static_assert(entity_flags::kOffloaded == Bit(schema::EntityFlags::Offloaded));
static_assert(entity_flags::kReportContacts == Bit(schema::EntityFlags::ReportContacts));
static_assert(Bit(schema::EntityFlags::ANY) == (entity_flags::kReportContacts << 1) - 1);

schema::Vec3 ToFb(const Vec3f& v) { return schema::Vec3(v.x, v.y, v.z); }
schema::Quat ToFb(const Quatf& q) { return schema::Quat(q.x, q.y, q.z, q.w); }

// An entity with one collider and, if `mass` is set, a dynamic rigid body of that mass.
EntitySpec OneCollider(uint32_t id, Vec3f position, Quatf rotation, ColliderSpec collider,
                       std::optional<float> mass) {
  EntitySpec e;
  e.id = id;
  e.position = position;
  e.rotation = rotation;
  if (mass) {
    e.rigid_body = RigidBodySpec{};
    e.rigid_body->mass = *mass;
  }
  e.colliders.push_back(std::move(collider));
  return e;
}

}  // namespace

std::vector<uint8_t> BuildContainer(const EntitySpec& spec) {
  flatbuffers::FlatBufferBuilder fbb(1024);
  schema::FinishContainerBuffer(fbb, AddContainer(fbb, spec));
  return {fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize()};
}

flatbuffers::Offset<schema::Container> AddContainer(flatbuffers::FlatBufferBuilder& fbb,
                                                    const EntitySpec& spec) {

  std::vector<flatbuffers::Offset<schema::Collider>> colliders;
  colliders.reserve(spec.colliders.size());
  for (const ColliderSpec& c : spec.colliders) {
    const schema::Vec3 he = ToFb(c.half_extents);
    const schema::Vec3 lp = ToFb(c.local_position);
    const schema::Quat lr = ToFb(c.local_rotation);
    colliders.push_back(schema::CreateColliderDirect(
        fbb, c.shape, &he, c.radius, c.height, &lp, &lr,
        c.vertices.empty() ? nullptr : &c.vertices, c.indices.empty() ? nullptr : &c.indices,
        c.is_trigger));
  }
  std::vector<flatbuffers::Offset<schema::Joint>> joints;
  for (const JointSpec& j : spec.joints) {
    const schema::Vec3 anchor = ToFb(j.anchor);
    const schema::Vec3 axis = ToFb(j.axis);
    joints.push_back(schema::CreateJoint(fbb, j.kind, j.connected_entity, &anchor, &axis,
                                         j.stiffness, j.damping));
  }
  flatbuffers::Offset<schema::RigidBody> rigid_body = 0;
  if (spec.rigid_body) {
    const RigidBodySpec& rb = *spec.rigid_body;
    const schema::Vec3 lv = ToFb(rb.linear_velocity);
    const schema::Vec3 av = ToFb(rb.angular_velocity);
    rigid_body = schema::CreateRigidBody(fbb, rb.mass, rb.linear_damping, rb.angular_damping,
                                         rb.friction, rb.restitution, rb.kinematic,
                                         rb.use_gravity, &lv, &av);
  }
  flatbuffers::Offset<schema::SoftBody> soft_body = 0;
  if (spec.soft_body) {
    const SoftBodySpec& sb = *spec.soft_body;
    soft_body = schema::CreateSoftBodyDirect(fbb, &sb.particles, &sb.masses, &sb.springs,
                                             sb.stiffness, sb.damping);
  }
  const schema::Transform transform(ToFb(spec.position), ToFb(spec.rotation), ToFb(spec.scale));
  return schema::CreateContainerDirect(
      fbb, spec.id, spec.parent_id, spec.owner, spec.flags, &transform,
      spec.name.empty() ? nullptr : spec.name.c_str(), rigid_body,
      colliders.empty() ? nullptr : &colliders, joints.empty() ? nullptr : &joints, soft_body,
      static_cast<schema::OwnerLeave>(spec.on_owner_leave));
}

ColliderSpec BoxCollider(Vec3f half_extents) {
  ColliderSpec c;
  c.shape = schema::ColliderShape::Box;
  c.half_extents = half_extents;
  return c;
}

ColliderSpec SphereCollider(float radius) {
  ColliderSpec c;
  c.shape = schema::ColliderShape::Sphere;
  c.radius = radius;
  return c;
}

EntitySpec StaticBox(uint32_t id, Vec3f position, Vec3f half_extents, Quatf rotation) {
  return OneCollider(id, position, rotation, BoxCollider(half_extents), std::nullopt);
}

EntitySpec DynamicBox(uint32_t id, Vec3f position, Vec3f half_extents, float mass) {
  return OneCollider(id, position, Quatf{}, BoxCollider(half_extents), mass);
}

EntitySpec DynamicSphere(uint32_t id, Vec3f position, float radius, float mass) {
  return OneCollider(id, position, Quatf{}, SphereCollider(radius), mass);
}

EntitySpec TriggerHand(uint32_t id, Vec3f position, float radius) {
  ColliderSpec trigger = SphereCollider(radius);
  trigger.is_trigger = true;
  EntitySpec e = OneCollider(id, position, Quatf{}, std::move(trigger), 0.0f);
  e.rigid_body->kinematic = true;
  return e;
}

}  // namespace edgephys
