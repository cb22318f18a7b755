// Internal to physics/: what the PhysicsWorld implementation files share. Not for
// callers of PhysicsWorld (include physics_world.h instead).
//
// The implementation is split by concern:
//   physics_world.cc         the front: construction, AddEntity/RemoveEntity, commands, Step(),
//                            output (CollectStates, DrainEvents, counters)
//   bullet_world.cc          the Bullet world, solver and solver settings (bullet_world.h)
//   container_validation.cc  Validate(): component limits, finite values, ids, parents, joints
//   body_builder.cc          AddEntity's build steps: shapes, rigid body, trigger, joints,
//                            soft body
//   stability_guard.cc       NaN / runaway speed / out of bounds / exploding soft body detection
//                            and restore
//   contact_tracker.cc       touching pairs -> Collision/Trigger Enter and Exit events
//   rest_manager.cc          freezing resting bodies and waking them (rest_manager.h)
//
// Thread-safety: as PhysicsWorld (none). Everything here is owned by one PhysicsWorld.
#pragma once

#include <BulletSoftBody/btSoftBody.h>
#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <unordered_map>
#include <vector>

#include "edgephys/schema/container_generated.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/rest_manager.h"

namespace edgephys::physics {
namespace internal {

enum class Kind : uint8_t { kTransformOnly, kStatic, kKinematic, kDynamic, kSoft };

// btCollisionObject::getUserIndex() of the objects an Entity owns (getUserPointer() is the
// Entity).
constexpr int kRoleBody = 0;
constexpr int kRoleTrigger = 1;

// --- Conversions and finiteness checks (pure, O(1)).

inline bool Finite(float v) { return std::isfinite(v); }
inline bool Finite(const schema::Vec3& v) {
  return Finite(v.x()) && Finite(v.y()) && Finite(v.z());
}
inline bool Finite(const schema::Quat& q) {
  return Finite(q.x()) && Finite(q.y()) && Finite(q.z()) && Finite(q.w());
}
inline bool Finite(const Vec3f& v) { return Finite(v.x) && Finite(v.y) && Finite(v.z); }
inline bool Finite(const Quatf& q) {
  return Finite(q.x) && Finite(q.y) && Finite(q.z) && Finite(q.w);
}
// Sum trick: NaN or inf in any component makes the sum non-finite.
inline bool Finite(const btVector3& v) { return std::isfinite(v.x() + v.y() + v.z()); }
inline bool Finite(const btTransform& t) {
  const btMatrix3x3& b = t.getBasis();
  return Finite(t.getOrigin()) && Finite(b[0]) && Finite(b[1]) && Finite(b[2]);
}

inline btVector3 ToBt(const schema::Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }
inline btVector3 ToBt(const Vec3f& v) { return btVector3(v.x, v.y, v.z); }
// The unit quaternion along (x, y, z, w), normalised in double: in float, components near
// FLT_MAX square to inf and denormal ones to 0, and either normalises to zeros, whose rotation
// matrix is NaN (2 / |q|^2 = inf times 0). Identity when the length is at most 1e-6 or not
// finite.
inline btQuaternion UnitOrIdentity(double x, double y, double z, double w) {
  const double l2 = x * x + y * y + z * z + w * w;
  if (!(l2 > 1e-12) || !std::isfinite(l2)) return btQuaternion::getIdentity();
  const double inv = 1.0 / std::sqrt(l2);
  return btQuaternion(static_cast<btScalar>(x * inv), static_cast<btScalar>(y * inv),
                      static_cast<btScalar>(z * inv), static_cast<btScalar>(w * inv));
}
// All-zero quaternions (a flatbuffers struct left at its default) mean identity.
inline btQuaternion ToBt(const schema::Quat& q) {
  return UnitOrIdentity(q.x(), q.y(), q.z(), q.w());
}
inline btQuaternion ToBt(const Quatf& q) { return UnitOrIdentity(q.x, q.y, q.z, q.w); }
// A quaternion ToBt can normalise: exactly all zero (identity, ToBt's own test) or of
// non-negligible length. The length is summed in double: in float, denormal components (say
// w = -5.8e-39) square to 0 and would pass as "all zero", which ToBt then normalises to NaN.
inline bool QuatUsable(const schema::Quat& q) {
  if (q.x() == 0 && q.y() == 0 && q.z() == 0 && q.w() == 0) return true;
  const double x = q.x(), y = q.y(), z = q.z(), w = q.w();
  return x * x + y * y + z * z + w * w > 1e-12;
}
// Inside the world bounds (the cube of PhysicsConfig::world_half_extent).
inline bool InsideWorld(float x, float y, float z, const PhysicsConfig& config) {
  const float b = config.world_half_extent;
  return std::abs(x) <= b && std::abs(y) <= b && std::abs(z) <= b;
}
inline bool InsideWorld(const Vec3f& p, const PhysicsConfig& config) {
  return InsideWorld(p.x, p.y, p.z, config);
}
inline bool InsideWorld(const schema::Vec3& p, const PhysicsConfig& config) {
  return InsideWorld(p.x(), p.y(), p.z(), config);
}
// A pose a command may set: finite, and its position inside the world bounds.
inline Status CheckPose(const Vec3f& pos, const Quatf& rot, const PhysicsConfig& config) {
  if (!Finite(pos) || !Finite(rot)) return Status(StatusCode::kInvalidArgument, "non-finite pose");
  if (!InsideWorld(pos, config)) {
    return Status(StatusCode::kInvalidArgument, "position outside the world bounds");
  }
  return Status::Ok();
}
inline Vec3f ToVec(const btVector3& v) { return Vec3f{v.x(), v.y(), v.z()}; }

inline EntityState ToState(uint32_t id, const btTransform& t) {
  EntityState s;
  s.entity_id = id;
  s.position = ToVec(t.getOrigin());
  const btQuaternion q = t.getRotation();
  s.rotation = Quatf{q.x(), q.y(), q.z(), q.w()};
  return s;
}

// Bitwise equality of position and rotation (what a receiver would see as "unchanged").
inline bool SameState(const EntityState& a, const EntityState& b) {
  return std::memcmp(&a.position, &b.position, sizeof(a.position)) == 0 &&
         std::memcmp(&a.rotation, &b.rotation, sizeof(a.rotation)) == 0;
}

// The container's scale; absent or all-zero means (1, 1, 1).
inline btVector3 ScaleOf(const schema::Container& c) {
  if (c.transform() == nullptr) return btVector3(1, 1, 1);
  const schema::Vec3& s = c.transform()->scale();
  if (s.x() == 0 && s.y() == 0 && s.z() == 0) return btVector3(1, 1, 1);
  return ToBt(s);
}

// The container's pose in the room frame (scale not included).
inline btTransform TransformOf(const schema::Container& c) {
  if (c.transform() == nullptr) return btTransform::getIdentity();
  return btTransform(ToBt(c.transform()->rotation()), ToBt(c.transform()->position()));
}

// Body mode of a (non-soft) container, as validation and building both read it: kinematic if
// it has a rigid body with the kinematic flag (RigidBody.kinematic or EntityFlags::Kinematic);
// dynamic if it has a rigid body that is not kinematic and has mass > 0.
inline bool IsKinematic(const schema::Container& c) {
  const schema::RigidBody* rb = c.rigid_body();
  return rb != nullptr &&
         (rb->kinematic() || (c.flags() & static_cast<uint32_t>(schema::EntityFlags::Kinematic)));
}
inline bool IsDynamic(const schema::Container& c) {
  const schema::RigidBody* rb = c.rigid_body();
  return rb != nullptr && !IsKinematic(c) && rb->mass() > 0;
}

// --- Validation (container_validation.cc).

using EntityMap = std::unordered_map<uint32_t, std::unique_ptr<PhysicsWorld::Entity>>;

// Checks `c` against `config` and the entities already in the world; kNone if it can be built.
// Reads only. O(size of the container).
InvalidReason ValidateContainer(const schema::Container& c, const PhysicsConfig& config,
                                const EntityMap& entities);
// The Status AddEntity returns for a rejected container (`why` != kNone).
Status RejectionStatus(InvalidReason why);

// --- Shapes (body_builder.cc).

// The collision shapes built for one entity. The entity owns every shape (Entity::shapes).
struct BodyShapes {
  btCollisionShape* body = nullptr;     // the rigid body's shape; nullptr: no rigid body
  btCollisionShape* trigger = nullptr;  // separate trigger object's shape; nullptr: none
  bool body_is_trigger = false;         // dynamic trigger-only entity: the body does not respond
  bool body_collides_nothing = false;   // dynamic entity without colliders: placeholder sphere
};

}  // namespace internal

// Receives Bullet's per-step transform of active dynamic bodies (and supplies the target of
// kinematic ones). Records the entity in the world's per-step list: O(1), no allocation once
// the list has grown.
class EntityMotionState : public btMotionState {
 public:
  EntityMotionState(PhysicsWorld* world, PhysicsWorld::Entity* entity, const btTransform& xf)
      : world_(world), entity_(entity), xf_(xf) {}
  void getWorldTransform(btTransform& out) const override { out = xf_; }
  void setWorldTransform(const btTransform& in) override;  // physics_world.cc
  btTransform& transform() { return xf_; }

 private:
  PhysicsWorld* world_;
  PhysicsWorld::Entity* entity_;
  btTransform xf_;
};

// A triangle mesh's scaled vertices and indices, which btBvhTriangleMeshShape references.
struct MeshData {
  std::vector<btScalar> vertices;
  std::vector<int> indices;
  std::unique_ptr<btTriangleIndexVertexArray> array;
};

struct PhysicsWorld::Entity {
  uint32_t id = 0;
  uint32_t parent_id = 0;
  uint32_t flags = 0;
  internal::Kind kind = internal::Kind::kTransformOnly;
  btTransform xf = btTransform::getIdentity();     // bodyless entities: world transform
  btTransform local = btTransform::getIdentity();  // transform-only child: pose in parent
  Entity* parent = nullptr;
  std::vector<Entity*> children;

  std::vector<std::unique_ptr<btCollisionShape>> shapes;  // owns every shape below
  std::vector<std::unique_ptr<MeshData>> meshes;
  std::unique_ptr<EntityMotionState> motion;
  std::unique_ptr<btRigidBody> body;
  std::unique_ptr<btCollisionObject> trigger;  // separate trigger object (mixed colliders)
  std::unique_ptr<btSoftBody> soft;

  btTransform last_good = btTransform::getIdentity();
  btVector3 gravity{0, 0, 0};
  btScalar radius = 0;  // bounding radius around the origin (bounds check)
  btScalar mass = 0;    // dynamic bodies: the container's mass (RestManager restores it)
  RestState rest;       // dynamic bodies: freezing (rest_manager.h)
  std::vector<btVector3> soft_good;
  btScalar soft_diag0 = 0;
  int soft_consecutive_resets = 0;

  btTransform target = btTransform::getIdentity();
  btTransform move_from = btTransform::getIdentity();  // kinematic: pose before this step
  bool has_target = false;
  bool pending_move = false;
  bool in_dirty = false;
  bool in_stepped = false;
  bool grabbed = false;
  uint32_t grabbed_by = 0;
  bool has_reported = false;
  EntityState reported;

  btTransform CurrentTransform() const {
    if (body) return body->getWorldTransform();
    if (soft) {
      btVector3 mn, mx;
      soft->getAabb(mn, mx);
      return btTransform(btQuaternion::getIdentity(), (mn + mx) * btScalar(0.5));
    }
    return xf;
  }
};

struct PhysicsWorld::JointRecord {
  uint32_t owner = 0;
  uint32_t other = 0;  // 0: the world
  std::unique_ptr<btTypedConstraint> constraint;
};

}  // namespace edgephys::physics
