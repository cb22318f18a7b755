#include "sdk/c_api_validate.h"

#include <cmath>
#include <cstddef>
#include <cstring>

namespace edgephys::capi {
namespace {

Vec3f V(const edgephys_vec3& v) { return {v.x, v.y, v.z}; }
Quatf Q(const edgephys_quat& q) { return {q.x, q.y, q.z, q.w}; }

Status Bad(const char* what, std::string detail) {
  return Status::InvalidArgument(what, std::move(detail));
}

bool NonNegative(float v) { return Finite(v) && v >= 0; }

Status CheckCollider(const edgephys_collider& c, size_t i, ColliderSpec* out) {
  const std::string where = "colliders[" + std::to_string(i) + "]";
  if (c.shape > EDGEPHYS_SHAPE_TRIANGLE_MESH) return Bad("bad collider", where + ".shape out of range");
  if (!FiniteVec(c.half_extents) || c.half_extents.x < 0 || c.half_extents.y < 0 ||
      c.half_extents.z < 0) {
    return Bad("bad collider", where + ".half_extents must be finite and >= 0");
  }
  if (!NonNegative(c.radius) || !NonNegative(c.height)) {
    return Bad("bad collider", where + ".radius/height must be finite and >= 0");
  }
  if (!FiniteVec(c.local_position) || std::fabs(c.local_position.x) > 1e6f ||
      std::fabs(c.local_position.y) > 1e6f || std::fabs(c.local_position.z) > 1e6f) {
    return Bad("bad collider", where + ".local_position must be finite");
  }
  if (!UnitQuat(c.local_rotation)) return Bad("bad collider", where + ".local_rotation must be a unit quaternion");
  if (c.is_trigger > 1) return Bad("bad collider", where + ".is_trigger must be 0 or 1");
  if (c.vertex_float_count > EDGEPHYS_MAX_MESH_FLOATS || c.index_count > EDGEPHYS_MAX_MESH_FLOATS) {
    return Bad("bad collider", where + ": mesh larger than EDGEPHYS_MAX_MESH_FLOATS");
  }
  if (c.vertex_float_count % 3 != 0 || c.index_count % 3 != 0) {
    return Bad("bad collider", where + ": vertex_float_count and index_count must be multiples of 3");
  }
  if ((c.vertex_float_count > 0 && c.vertices == nullptr) || (c.index_count > 0 && c.indices == nullptr)) {
    return Bad("bad collider", where + ": NULL vertices/indices with a non-zero count");
  }
  if (c.shape == EDGEPHYS_SHAPE_CONVEX_HULL && c.vertex_float_count < 9) {
    return Bad("bad collider", where + ": a convex hull needs at least 3 vertices");
  }
  if (c.shape == EDGEPHYS_SHAPE_TRIANGLE_MESH && c.index_count < 3) {
    return Bad("bad collider", where + ": a triangle mesh needs at least one triangle");
  }
  for (uint32_t k = 0; k < c.vertex_float_count; ++k) {
    if (!Finite(c.vertices[k])) return Bad("bad collider", where + ".vertices not finite");
  }
  const uint32_t vertex_count = c.vertex_float_count / 3;
  for (uint32_t k = 0; k < c.index_count; ++k) {
    if (c.indices[k] >= vertex_count) return Bad("bad collider", where + ".indices out of range");
  }
  out->shape = static_cast<schema::ColliderShape>(c.shape);
  out->half_extents = V(c.half_extents);
  out->radius = c.radius;
  out->height = c.height;
  out->local_position = V(c.local_position);
  out->local_rotation = Q(c.local_rotation);
  out->vertices.assign(c.vertices, c.vertices + c.vertex_float_count);
  out->indices.assign(c.indices, c.indices + c.index_count);
  out->is_trigger = c.is_trigger != 0;
  return Status::Ok();
}

Status CheckRigidBody(const edgephys_rigid_body& b, RigidBodySpec* out) {
  if (!NonNegative(b.mass) || !NonNegative(b.linear_damping) || !NonNegative(b.angular_damping) ||
      !NonNegative(b.friction) || !NonNegative(b.restitution)) {
    return Bad("bad rigid body", "mass, damping, friction and restitution must be finite and >= 0");
  }
  if (b.kinematic > 1 || b.use_gravity > 1) return Bad("bad rigid body", "kinematic/use_gravity must be 0 or 1");
  if (!FiniteVec(b.linear_velocity) || !FiniteVec(b.angular_velocity)) {
    return Bad("bad rigid body", "velocities must be finite");
  }
  out->mass = b.mass;
  out->linear_damping = b.linear_damping;
  out->angular_damping = b.angular_damping;
  out->friction = b.friction;
  out->restitution = b.restitution;
  out->kinematic = b.kinematic != 0;
  out->use_gravity = b.use_gravity != 0;
  out->linear_velocity = V(b.linear_velocity);
  out->angular_velocity = V(b.angular_velocity);
  return Status::Ok();
}

Status CheckJoint(const edgephys_joint& j, size_t i, JointSpec* out) {
  const std::string where = "joints[" + std::to_string(i) + "]";
  if (j.kind > EDGEPHYS_JOINT_SPRING) return Bad("bad joint", where + ".kind out of range");
  if (!FiniteVec(j.anchor) || !FiniteVec(j.axis)) return Bad("bad joint", where + ": anchor/axis not finite");
  if (!NonNegative(j.stiffness) || !NonNegative(j.damping)) {
    return Bad("bad joint", where + ": stiffness/damping must be finite and >= 0");
  }
  out->kind = static_cast<schema::JointKind>(j.kind);
  out->connected_entity = j.connected_entity;
  out->anchor = V(j.anchor);
  out->axis = V(j.axis);
  out->stiffness = j.stiffness;
  out->damping = j.damping;
  return Status::Ok();
}

Status CheckSoftBody(const edgephys_soft_body& s, SoftBodySpec* out) {
  if (s.particle_count == 0 || s.particle_count > EDGEPHYS_MAX_SOFT_BODY_PARTICLES) {
    return Bad("bad soft body", "particle_count must be 1..EDGEPHYS_MAX_SOFT_BODY_PARTICLES");
  }
  if (s.spring_count > EDGEPHYS_MAX_SOFT_BODY_SPRINGS) {
    return Bad("bad soft body", "spring_count above EDGEPHYS_MAX_SOFT_BODY_SPRINGS");
  }
  if (s.particles == nullptr || s.masses == nullptr || (s.spring_count > 0 && s.springs == nullptr)) {
    return Bad("bad soft body", "NULL particles, masses or springs");
  }
  if (!NonNegative(s.stiffness) || !Finite(s.damping) || s.damping < 0 || s.damping > 1) {
    return Bad("bad soft body", "stiffness must be >= 0 and damping in [0, 1]");
  }
  for (uint32_t k = 0; k < s.particle_count * 3; ++k) {
    if (!Finite(s.particles[k]) || std::fabs(s.particles[k]) > 1e6f) {
      return Bad("bad soft body", "particles must be finite");
    }
  }
  for (uint32_t k = 0; k < s.particle_count; ++k) {
    if (!Finite(s.masses[k]) || s.masses[k] <= 0) return Bad("bad soft body", "masses must be finite and > 0");
  }
  for (uint32_t k = 0; k < s.spring_count * 2; ++k) {
    if (s.springs[k] >= s.particle_count) return Bad("bad soft body", "spring index out of range");
  }
  out->particles.assign(s.particles, s.particles + size_t{s.particle_count} * 3);
  out->masses.assign(s.masses, s.masses + s.particle_count);
  out->springs.assign(s.springs, s.springs + size_t{s.spring_count} * 2);
  out->stiffness = s.stiffness;
  out->damping = s.damping;
  return Status::Ok();
}

}  // namespace

bool Finite(float v) { return std::isfinite(v); }
bool FiniteVec(const edgephys_vec3& v) { return Finite(v.x) && Finite(v.y) && Finite(v.z); }
bool UnitQuat(const edgephys_quat& q) {
  if (!Finite(q.x) || !Finite(q.y) || !Finite(q.z) || !Finite(q.w)) return false;
  const float n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return std::fabs(n - 1.0f) <= 1e-3f;
}

Status CheckTransform(const edgephys_transform& t, const char* what) {
  const edgephys_vec3& p = t.position;
  if (!FiniteVec(p) || std::fabs(p.x) > 1e6f || std::fabs(p.y) > 1e6f || std::fabs(p.z) > 1e6f) {
    return Status::InvalidArgument(what, "position must be finite and within 1e6 m");
  }
  if (!UnitQuat(t.rotation)) return Status::InvalidArgument(what, "rotation must be a finite unit quaternion");
  return Status::Ok();
}

Status ToEntitySpec(const edgephys_spawn_desc& desc, EntitySpec* spec) {
  constexpr size_t kBeforeOwnerLeave = offsetof(edgephys_spawn_desc, on_owner_leave);
  if (desc.struct_size != sizeof(edgephys_spawn_desc) && desc.struct_size != kBeforeOwnerLeave) {
    return Bad("bad spawn desc", "struct_size is not sizeof(edgephys_spawn_desc): call edgephys_spawn_desc_init");
  }
  if (Status st = CheckTransform(desc.transform, "bad spawn transform"); !st.ok()) return st;
  if (!FiniteVec(desc.scale) || desc.scale.x <= 0 || desc.scale.y <= 0 || desc.scale.z <= 0) {
    return Bad("bad spawn desc", "scale must be finite and > 0");
  }
  if ((desc.flags & ~EDGEPHYS_FLAG_ALL) != 0) return Bad("bad spawn desc", "unknown flag bits");
  if (desc.collider_count > EDGEPHYS_MAX_COLLIDERS) return Bad("bad spawn desc", "collider_count above EDGEPHYS_MAX_COLLIDERS");
  if (desc.joint_count > EDGEPHYS_MAX_JOINTS) return Bad("bad spawn desc", "joint_count above EDGEPHYS_MAX_JOINTS");
  if ((desc.collider_count > 0 && desc.colliders == nullptr) || (desc.joint_count > 0 && desc.joints == nullptr)) {
    return Bad("bad spawn desc", "NULL colliders/joints with a non-zero count");
  }
  EntitySpec s;
  if (desc.name != nullptr) {
    const size_t n = strnlen(desc.name, EDGEPHYS_MAX_NAME_BYTES + 1);
    if (n > EDGEPHYS_MAX_NAME_BYTES) return Bad("bad spawn desc", "name longer than EDGEPHYS_MAX_NAME_BYTES");
    s.name.assign(desc.name, n);
  }
  s.position = V(desc.transform.position);
  s.rotation = Q(desc.transform.rotation);
  s.scale = V(desc.scale);
  s.parent_id = desc.parent_id;
  s.flags = desc.flags;
  if (desc.struct_size == sizeof(edgephys_spawn_desc)) {
    if (desc.on_owner_leave > EDGEPHYS_OWNER_LEAVE_DESPAWN) {
      return Bad("bad spawn desc", "on_owner_leave is not an EDGEPHYS_OWNER_LEAVE_* value");
    }
    s.on_owner_leave = static_cast<uint8_t>(desc.on_owner_leave);
  }
  if (desc.rigid_body != nullptr) {
    RigidBodySpec body;
    if (Status st = CheckRigidBody(*desc.rigid_body, &body); !st.ok()) return st;
    s.rigid_body = body;
  }
  s.colliders.resize(desc.collider_count);
  for (uint32_t i = 0; i < desc.collider_count; ++i) {
    if (Status st = CheckCollider(desc.colliders[i], i, &s.colliders[i]); !st.ok()) return st;
  }
  s.joints.resize(desc.joint_count);
  for (uint32_t i = 0; i < desc.joint_count; ++i) {
    if (Status st = CheckJoint(desc.joints[i], i, &s.joints[i]); !st.ok()) return st;
  }
  if (desc.soft_body != nullptr) {
    SoftBodySpec soft;
    if (Status st = CheckSoftBody(*desc.soft_body, &soft); !st.ok()) return st;
    s.soft_body = std::move(soft);
  }
  *spec = std::move(s);
  return Status::Ok();
}

}  // namespace edgephys::capi
