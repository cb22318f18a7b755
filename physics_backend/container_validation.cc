// Validation of dissected containers before PhysicsWorld builds anything from them: ids and
// parents, finite values, ranges, component limits, mesh sanity, joint targets. Pure reads;
// the checks run in a fixed order, so a container with several faults always reports the same
// InvalidReason.
#include <algorithm>
#include <cmath>

#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {
namespace internal {
namespace {

using R = InvalidReason;

// The masses a dynamic body or a soft-body particle may have (kg).
constexpr float kMinMass = 1e-6f;
constexpr float kMaxMass = 1e9f;

// Rejects hulls whose points span no volume. O(n).
bool HullHasVolume(const flatbuffers::Vector<float>& v, const btVector3& scale) {
  const size_t n = v.size() / 3;
  auto at = [&](size_t i) { return btVector3(v[3 * i], v[3 * i + 1], v[3 * i + 2]) * scale; };
  const btVector3 p0 = at(0);
  size_t i1 = 0;
  btScalar best = 0;
  for (size_t i = 1; i < n; ++i) {
    const btScalar d = (at(i) - p0).length2();
    if (d > best) best = d, i1 = i;
  }
  if (best < btScalar(1e-12)) return false;
  const btVector3 e1 = at(i1) - p0;
  btVector3 normal(0, 0, 0);
  best = 0;
  for (size_t i = 1; i < n; ++i) {
    const btVector3 c = e1.cross(at(i) - p0);
    if (c.length2() > best) best = c.length2(), normal = c;
  }
  if (best < btScalar(1e-16)) return false;
  normal.normalize();
  btScalar height = 0;
  for (size_t i = 1; i < n; ++i) height = std::max(height, std::abs(normal.dot(at(i) - p0)));
  return height > btScalar(1e-5);
}

// Entity id, duplicate id, parent.
InvalidReason ValidateIds(const schema::Container& c, const EntityMap& entities) {
  if (c.entity_id() == 0) return R::kZeroId;
  if (entities.count(c.entity_id()) != 0) return R::kDuplicateId;
  if (c.parent_id() != 0 &&
      (c.parent_id() == c.entity_id() || entities.count(c.parent_id()) == 0)) {
    return R::kUnknownParent;
  }
  return R::kNone;
}

// Position, rotation, scale: finite, usable, inside the world bounds, positive scale.
InvalidReason ValidateTransform(const schema::Container& c, const PhysicsConfig& config) {
  const schema::Transform* t = c.transform();
  if (t == nullptr) return R::kNone;
  if (!Finite(t->position()) || !Finite(t->rotation()) || !Finite(t->scale())) return R::kNaN;
  if (!QuatUsable(t->rotation())) return R::kOutOfRange;
  if (!InsideWorld(t->position(), config)) return R::kOutOfRange;
  const btVector3 s = ScaleOf(c);
  if (s.x() <= 0 || s.y() <= 0 || s.z() <= 0) return R::kOutOfRange;
  return R::kNone;
}

// A soft-body container: particles, masses, springs, material; no joints.
InvalidReason ValidateSoftBody(const schema::Container& c, const PhysicsConfig& config) {
  const schema::SoftBody* sb = c.soft_body();
  if (!config.soft_body_world) return R::kSoftBodiesDisabled;
  const auto* particles = sb->particles();
  if (particles == nullptr || particles->size() == 0 || particles->size() % 3 != 0) {
    return R::kBadSoftBody;
  }
  const size_t n = particles->size() / 3;
  if (n > config.max_soft_nodes) return R::kTooManyNodes;
  const float bound = config.world_half_extent;
  for (float v : *particles) {
    if (!Finite(v)) return R::kNaN;
    if (std::abs(v) > bound) return R::kOutOfRange;
  }
  if (const auto* masses = sb->masses(); masses != nullptr && masses->size() != 0) {
    if (masses->size() != n) return R::kBadSoftBody;
    for (float m : *masses) {
      if (!Finite(m)) return R::kNaN;
      if (m < 0) return R::kNegativeMass;
      // 0 pins the particle; otherwise the range of a dynamic body's mass (1 mg to 1e9 kg):
      // Bullet stores 1 / mass in float, which a 1e-39 kg particle overflows to inf.
      if (m != 0 && (m < kMinMass || m > kMaxMass)) return R::kOutOfRange;
    }
  }
  if (const auto* springs = sb->springs()) {
    if (springs->size() % 2 != 0) return R::kBadSoftBody;
    if (springs->size() / 2 > config.max_soft_springs) return R::kTooManyNodes;
    for (size_t i = 0; i < springs->size(); i += 2) {
      const uint32_t a = springs->Get(i), b = springs->Get(i + 1);
      if (a >= n || b >= n || a == b) return R::kBadSoftBody;
    }
  }
  if (!Finite(sb->stiffness()) || !Finite(sb->damping())) return R::kNaN;
  if (sb->stiffness() < 0 || sb->damping() < 0 || sb->damping() > 1) return R::kOutOfRange;
  if (c.joints() != nullptr && c.joints()->size() != 0) return R::kBadJoint;
  return R::kNone;
}

// Speed of a velocity, in double (a float square of 1e30 would overflow).
double Speed(const schema::Vec3& v) {
  return std::sqrt(double{v.x()} * v.x() + double{v.y()} * v.y() + double{v.z()} * v.z());
}

// The rigid body component (if any): finite, non-negative mass, damping/restitution in [0, 1],
// initial velocities within the stability guard's speeds (PhysicsConfig::max_linear_speed,
// max_angular_speed: a faster body would be reset on its first step anyway).
InvalidReason ValidateRigidBody(const schema::Container& c, const PhysicsConfig& config) {
  const schema::RigidBody* rb = c.rigid_body();
  if (rb == nullptr) return R::kNone;
  if (!Finite(rb->mass()) || !Finite(rb->linear_damping()) || !Finite(rb->angular_damping()) ||
      !Finite(rb->friction()) || !Finite(rb->restitution())) {
    return R::kNaN;
  }
  if (rb->linear_velocity() && !Finite(*rb->linear_velocity())) return R::kNaN;
  if (rb->angular_velocity() && !Finite(*rb->angular_velocity())) return R::kNaN;
  if (rb->linear_velocity() && Speed(*rb->linear_velocity()) > config.max_linear_speed) {
    return R::kOutOfRange;
  }
  if (rb->angular_velocity() && Speed(*rb->angular_velocity()) > config.max_angular_speed) {
    return R::kOutOfRange;
  }
  if (rb->mass() < 0) return R::kNegativeMass;
  // A dynamic body from 1 mg to a million tonnes: outside it float inverse masses and inertias
  // overflow or swamp every contact, and the guard would reset the body on every step.
  if (!rb->kinematic() && rb->mass() > 0 && (rb->mass() < kMinMass || rb->mass() > kMaxMass)) {
    return R::kOutOfRange;
  }
  if (rb->linear_damping() < 0 || rb->linear_damping() > 1 || rb->angular_damping() < 0 ||
      rb->angular_damping() > 1 || rb->friction() < 0 || rb->restitution() < 0 ||
      rb->restitution() > 1) {
    return R::kOutOfRange;
  }
  return R::kNone;
}

// Triangle mesh indices: in range, at least one triangle with area (after scaling).
InvalidReason ValidateMeshIndices(const schema::Collider& col, const PhysicsConfig& config,
                                  const btVector3& scale) {
  const auto* v = col.vertices();
  const size_t nv = v->size() / 3;
  const auto* idx = col.indices();
  if (nv < 3 || idx == nullptr || idx->size() < 3 || idx->size() % 3 != 0) {
    return R::kDegenerateMesh;
  }
  if (idx->size() / 3 > config.max_mesh_triangles) return R::kTooManyNodes;
  bool any_area = false;
  for (size_t t = 0; t < idx->size(); t += 3) {
    const uint32_t i0 = idx->Get(t), i1 = idx->Get(t + 1), i2 = idx->Get(t + 2);
    if (i0 >= nv || i1 >= nv || i2 >= nv) return R::kDegenerateMesh;
    const btVector3 a(v->Get(3 * i0), v->Get(3 * i0 + 1), v->Get(3 * i0 + 2));
    const btVector3 b(v->Get(3 * i1), v->Get(3 * i1 + 1), v->Get(3 * i1 + 2));
    const btVector3 d(v->Get(3 * i2), v->Get(3 * i2 + 1), v->Get(3 * i2 + 2));
    if (((b - a) * scale).cross((d - a) * scale).length2() > btScalar(1e-16)) {
      any_area = true;
    }
  }
  return any_area ? R::kNone : R::kDegenerateMesh;
}

// A scaled size a collider may have: from 0.1 mm (below it a float product may have
// underflowed, and Bullet's contact tolerances of centimetres make the shape meaningless) to
// the world's width (a shape of 1e30 m is a unit error, and Bullet's float broadphase and
// sparse SDF lose all precision). Offsets and vertices likewise stay within the world's width.
constexpr float kMinColliderSize = 1e-4f;  // m
float WorldWidth(const PhysicsConfig& config) { return 2 * config.world_half_extent; }
bool SizeUsable(float scaled, const PhysicsConfig& config) {
  return scaled >= kMinColliderSize && scaled <= WorldWidth(config);
}
bool OffsetUsable(const btVector3& scaled, const PhysicsConfig& config) {
  const float width = WorldWidth(config);
  return std::abs(scaled.x()) <= width && std::abs(scaled.y()) <= width &&
         std::abs(scaled.z()) <= width;
}

// ConvexHull and TriangleMesh colliders. A triangle mesh on a dynamic entity is built as the
// hull of its vertices, so it must also be a valid hull.
InvalidReason ValidateVertexCollider(const schema::Collider& col, const PhysicsConfig& config,
                                     const btVector3& scale, bool dynamic) {
  const auto* v = col.vertices();
  if (v == nullptr || v->size() % 3 != 0) return R::kDegenerateMesh;
  const size_t nv = v->size() / 3;
  if (nv > config.max_mesh_vertices) return R::kTooManyNodes;
  for (float f : *v) {
    if (!Finite(f)) return R::kNaN;
  }
  for (size_t i = 0; i < nv; ++i) {
    const btVector3 p(v->Get(3 * i), v->Get(3 * i + 1), v->Get(3 * i + 2));
    if (!OffsetUsable(p * scale, config)) return R::kOutOfRange;
  }
  const bool hull = col.shape() == schema::ColliderShape::ConvexHull || dynamic;
  if (col.shape() == schema::ColliderShape::TriangleMesh) {
    if (const InvalidReason r = ValidateMeshIndices(col, config, scale); r != R::kNone) return r;
  }
  if (hull && (nv < 4 || !HullHasVolume(*v, scale))) return R::kDegenerateMesh;
  return R::kNone;
}

// One collider: finite local pose and sizes, then the shape's own constraints.
InvalidReason ValidateCollider(const schema::Collider& col, const PhysicsConfig& config,
                               const btVector3& scale, bool dynamic) {
  if (col.half_extents() && !Finite(*col.half_extents())) return R::kNaN;
  if (col.local_position() && !Finite(*col.local_position())) return R::kNaN;
  if (col.local_rotation() && !Finite(*col.local_rotation())) return R::kNaN;
  if (!Finite(col.radius()) || !Finite(col.height())) return R::kNaN;
  if (col.local_rotation() && !QuatUsable(*col.local_rotation())) return R::kOutOfRange;
  if (col.local_position() && !OffsetUsable(ToBt(*col.local_position()) * scale, config)) {
    return R::kOutOfRange;
  }
  const float smax = std::max({scale.x(), scale.y(), scale.z()});
  switch (col.shape()) {
    case schema::ColliderShape::Box:
    case schema::ColliderShape::Cylinder: {
      const schema::Vec3* he = col.half_extents();
      if (he == nullptr || !SizeUsable(he->x() * scale.x(), config) ||
          !SizeUsable(he->y() * scale.y(), config) || !SizeUsable(he->z() * scale.z(), config)) {
        return R::kOutOfRange;
      }
      return R::kNone;
    }
    case schema::ColliderShape::Sphere:
      return SizeUsable(col.radius() * smax, config) ? R::kNone : R::kOutOfRange;
    case schema::ColliderShape::Capsule:
      return SizeUsable(col.radius() * smax, config) && col.height() >= 0 &&
                     col.height() * scale.y() <= WorldWidth(config)
                 ? R::kNone
                 : R::kOutOfRange;
    case schema::ColliderShape::ConvexHull:
    case schema::ColliderShape::TriangleMesh:
      return ValidateVertexCollider(col, config, scale, dynamic);
    default:
      return R::kUnknownShape;
  }
}

InvalidReason ValidateColliders(const schema::Container& c, const PhysicsConfig& config,
                                bool dynamic) {
  const auto* colliders = c.colliders();
  if (colliders == nullptr) return R::kNone;
  if (colliders->size() > config.max_colliders) return R::kTooManyColliders;
  const btVector3 scale = ScaleOf(c);
  for (const schema::Collider* col : *colliders) {
    if (const InvalidReason r = ValidateCollider(*col, config, scale, dynamic); r != R::kNone) {
      return r;
    }
  }
  return R::kNone;
}

// One joint: finite values, known kind, ranges, a body to attach to, an existing partner.
InvalidReason ValidateJoint(const schema::Joint& j, const schema::Container& c, bool dynamic,
                            const EntityMap& entities) {
  if (j.anchor() && !Finite(*j.anchor())) return R::kNaN;
  if (j.axis() && !Finite(*j.axis())) return R::kNaN;
  if (!Finite(j.stiffness()) || !Finite(j.damping())) return R::kNaN;
  if (j.kind() > schema::JointKind::MAX) return R::kUnknownShape;
  if (j.stiffness() < 0 || j.damping() < 0) return R::kOutOfRange;
  if (j.kind() == schema::JointKind::Hinge &&
      (j.axis() == nullptr || ToBt(*j.axis()).length2() < btScalar(1e-12))) {
    return R::kOutOfRange;
  }
  const schema::RigidBody* rb = c.rigid_body();
  if (rb == nullptr || c.colliders() == nullptr || c.colliders()->size() == 0 ||
      (!dynamic && !rb->kinematic())) {
    return R::kBadJoint;
  }
  if (j.connected_entity() != 0) {
    auto it = entities.find(j.connected_entity());
    if (j.connected_entity() == c.entity_id() || it == entities.end() || !it->second->body) {
      return R::kUnknownJointTarget;
    }
  }
  return R::kNone;
}

InvalidReason ValidateJoints(const schema::Container& c, const PhysicsConfig& config, bool dynamic,
                             const EntityMap& entities) {
  const auto* joints = c.joints();
  if (joints == nullptr) return R::kNone;
  if (joints->size() > config.max_joints) return R::kTooManyColliders;
  for (const schema::Joint* j : *joints) {
    if (const InvalidReason r = ValidateJoint(*j, c, dynamic, entities); r != R::kNone) return r;
  }
  return R::kNone;
}

}  // namespace

InvalidReason ValidateContainer(const schema::Container& c, const PhysicsConfig& config,
                                const EntityMap& entities) {
  if (const InvalidReason r = ValidateIds(c, entities); r != R::kNone) return r;
  if (const InvalidReason r = ValidateTransform(c, config); r != R::kNone) return r;
  // A soft body entity ignores rigid_body and colliders.
  if (c.soft_body() != nullptr) return ValidateSoftBody(c, config);
  if (const InvalidReason r = ValidateRigidBody(c, config); r != R::kNone) return r;
  const bool dynamic = IsDynamic(c);
  if (const InvalidReason r = ValidateColliders(c, config, dynamic); r != R::kNone) return r;
  return ValidateJoints(c, config, dynamic, entities);
}

Status RejectionStatus(InvalidReason why) {
  switch (why) {
    case InvalidReason::kDuplicateId:
      return Status(StatusCode::kAlreadyExists, "duplicate entity id");
    case InvalidReason::kTooManyNodes:
    case InvalidReason::kTooManyColliders:
      return Status(StatusCode::kTooLarge, "container over the configured limits");
    default:
      return Status(StatusCode::kInvalidArgument, "invalid container");
  }
}

}  // namespace internal

std::string_view InvalidReasonName(InvalidReason reason) {
  switch (reason) {
    case InvalidReason::kNone: return "none";
    case InvalidReason::kZeroId: return "entity id 0 is reserved";
    case InvalidReason::kNaN: return "non-finite number";
    case InvalidReason::kNegativeMass: return "negative mass";
    case InvalidReason::kOutOfRange: return "value out of range";
    case InvalidReason::kDegenerateMesh: return "degenerate mesh";
    case InvalidReason::kTooManyNodes: return "too many nodes";
    case InvalidReason::kTooManyColliders: return "too many colliders or joints";
    case InvalidReason::kUnknownShape: return "unknown collider shape or joint kind";
    case InvalidReason::kDuplicateId: return "duplicate entity id";
    case InvalidReason::kUnknownParent: return "unknown parent";
    case InvalidReason::kUnknownJointTarget: return "unknown joint target";
    case InvalidReason::kBadJoint: return "joint on an entity without a rigid body";
    case InvalidReason::kBadSoftBody: return "inconsistent soft body";
    case InvalidReason::kSoftBodiesDisabled: return "soft bodies disabled";
  }
  return "unknown";
}

}  // namespace edgephys::physics
