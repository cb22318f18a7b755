#include "physics_backend/physics_world.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "edgephys/schema/container_generated.h"

namespace edgephys::physics {
namespace {

enum class Kind : uint8_t { kTransformOnly, kStatic, kKinematic, kDynamic, kSoft };

constexpr int kRoleBody = 0;
constexpr int kRoleTrigger = 1;

bool Finite(float v) { return std::isfinite(v); }
bool Finite(const schema::Vec3& v) { return Finite(v.x()) && Finite(v.y()) && Finite(v.z()); }
bool Finite(const schema::Quat& q) {
  return Finite(q.x()) && Finite(q.y()) && Finite(q.z()) && Finite(q.w());
}
bool Finite(const Vec3f& v) { return Finite(v.x) && Finite(v.y) && Finite(v.z); }
bool Finite(const Quatf& q) { return Finite(q.x) && Finite(q.y) && Finite(q.z) && Finite(q.w); }
// Sum trick: NaN or inf in any component makes the sum non-finite.
bool Finite(const btVector3& v) { return std::isfinite(v.x() + v.y() + v.z()); }
bool Finite(const btTransform& t) {
  const btMatrix3x3& b = t.getBasis();
  return Finite(t.getOrigin()) && Finite(b[0]) && Finite(b[1]) && Finite(b[2]);
}

btVector3 ToBt(const schema::Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }
btVector3 ToBt(const Vec3f& v) { return btVector3(v.x, v.y, v.z); }
// All-zero quaternions (a flatbuffers struct left at its default) mean identity.
btQuaternion ToBt(const schema::Quat& q) {
  if (q.x() == 0 && q.y() == 0 && q.z() == 0 && q.w() == 0) return btQuaternion::getIdentity();
  btQuaternion r(q.x(), q.y(), q.z(), q.w());
  return r.normalized();
}
btQuaternion ToBt(const Quatf& q) {
  btQuaternion r(q.x, q.y, q.z, q.w);
  const btScalar len = r.length();
  return len > btScalar(1e-6) ? r / len : btQuaternion::getIdentity();
}
bool QuatUsable(const schema::Quat& q) {
  const float l2 = q.x() * q.x() + q.y() * q.y() + q.z() * q.z() + q.w() * q.w();
  return l2 == 0.0f || l2 > 1e-12f;
}
Vec3f ToVec(const btVector3& v) { return Vec3f{v.x(), v.y(), v.z()}; }

EntityState ToState(uint32_t id, const btTransform& t) {
  EntityState s;
  s.entity_id = id;
  s.position = ToVec(t.getOrigin());
  const btQuaternion q = t.getRotation();
  s.rotation = Quatf{q.x(), q.y(), q.z(), q.w()};
  return s;
}

bool SameState(const EntityState& a, const EntityState& b) {
  return std::memcmp(&a.position, &b.position, sizeof(a.position)) == 0 &&
         std::memcmp(&a.rotation, &b.rotation, sizeof(a.rotation)) == 0;
}

btVector3 ScaleOf(const schema::Container& c) {
  if (c.transform() == nullptr) return btVector3(1, 1, 1);
  const schema::Vec3& s = c.transform()->scale();
  if (s.x() == 0 && s.y() == 0 && s.z() == 0) return btVector3(1, 1, 1);
  return ToBt(s);
}

btTransform TransformOf(const schema::Container& c) {
  if (c.transform() == nullptr) return btTransform::getIdentity();
  return btTransform(ToBt(c.transform()->rotation()), ToBt(c.transform()->position()));
}

// A frame whose Z axis is `axis` (unit) and origin `origin`.
btTransform FrameWithZ(const btVector3& origin, const btVector3& axis) {
  const btVector3 z(0, 0, 1);
  btQuaternion q = btQuaternion::getIdentity();
  if (axis.dot(z) < btScalar(-0.9999)) {
    q = btQuaternion(btVector3(1, 0, 0), SIMD_PI);
  } else {
    q = shortestArcQuat(z, axis);
  }
  return btTransform(q, origin);
}

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

}  // namespace

// Receives Bullet's per-step transform of active dynamic bodies (and supplies the target of
// kinematic ones). Records the entity in the world's per-step list: O(1), no allocation once
// the list has grown.
class EntityMotionState : public btMotionState {
 public:
  EntityMotionState(PhysicsWorld* world, PhysicsWorld::Entity* entity, const btTransform& xf)
      : world_(world), entity_(entity), xf_(xf) {}
  void getWorldTransform(btTransform& out) const override { out = xf_; }
  void setWorldTransform(const btTransform& in) override;
  btTransform& transform() { return xf_; }

 private:
  PhysicsWorld* world_;
  PhysicsWorld::Entity* entity_;
  btTransform xf_;
};

struct MeshData {
  std::vector<btScalar> vertices;
  std::vector<int> indices;
  std::unique_ptr<btTriangleIndexVertexArray> array;
};

struct PhysicsWorld::Entity {
  uint32_t id = 0;
  uint32_t parent_id = 0;
  uint32_t flags = 0;
  Kind kind = Kind::kTransformOnly;
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

void EntityMotionState::setWorldTransform(const btTransform& in) {
  xf_ = in;
  if (!entity_->in_stepped) {
    entity_->in_stepped = true;
    world_->stepped_.push_back(entity_);
  }
}

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

PhysicsWorld::PhysicsWorld(const PhysicsConfig& config) : config_(config) {
  if (config_.soft_body_world) {
    collision_config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
  } else {
    collision_config_ = std::make_unique<btDefaultCollisionConfiguration>();
  }
  dispatcher_ = std::make_unique<btCollisionDispatcher>(collision_config_.get());
  broadphase_ = std::make_unique<btDbvtBroadphase>();
  solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
  if (config_.soft_body_world) {
    auto w = std::make_unique<btSoftRigidDynamicsWorld>(dispatcher_.get(), broadphase_.get(),
                                                         solver_.get(), collision_config_.get());
    soft_info_ = &w->getWorldInfo();
    world_ = std::move(w);
  } else {
    world_ = std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(),
                                                        solver_.get(), collision_config_.get());
  }
  const btVector3 g = ToBt(config_.gravity);
  world_->setGravity(g);
  if (soft_info_ != nullptr) {
    soft_info_->m_gravity = g;
    soft_info_->air_density = 0;
    soft_info_->water_density = 0;
  }
  world_->getSolverInfo().m_numIterations = config_.solver_iterations;
  // Static AABBs never change unless we move them (we then update them explicitly).
  world_->setForceUpdateAllAabbs(false);
  // CCD creates predictive contacts; without this they silently drop restitution.
  world_->setApplySpeculativeContactRestitution(true);
  fixed_body_ = std::make_unique<btRigidBody>(0, nullptr, nullptr);
  fixed_body_->setMassProps(0, btVector3(0, 0, 0));
  const size_t reserve = 1024;
  stepped_.reserve(reserve);
  dirty_.reserve(reserve);
  pairs_.reserve(reserve);
  new_pairs_.reserve(reserve);
  events_.reserve(256);
  step_events_.reserve(256);
}

PhysicsWorld::~PhysicsWorld() {
  for (auto& j : joints_) world_->removeConstraint(j->constraint.get());
  joints_.clear();
  for (auto& [id, e] : entities_) {
    if (e->body) world_->removeRigidBody(e->body.get());
    if (e->trigger) world_->removeCollisionObject(e->trigger.get());
    if (e->soft) static_cast<btSoftRigidDynamicsWorld*>(world_.get())->removeSoftBody(e->soft.get());
  }
  entities_.clear();
  world_.reset();
}

PhysicsWorld::Entity* PhysicsWorld::Find(uint32_t id) const {
  auto it = entities_.find(id);
  return it == entities_.end() ? nullptr : it->second.get();
}

bool PhysicsWorld::HasEntity(uint32_t id) const { return Find(id) != nullptr; }

void PhysicsWorld::MarkDirty(Entity* e) {
  if (!e->in_dirty) {
    e->in_dirty = true;
    dirty_.push_back(e);
  }
}

void PhysicsWorld::PushEvent(const PhysicsEvent& ev) {
  if (events_.size() >= config_.max_pending_events) {
    ++stats_.events_dropped;
    return;
  }
  events_.push_back(ev);
}

// ---------------------------------------------------------------------------------------------
// Validation

InvalidReason PhysicsWorld::Validate(const schema::Container& c) const {
  using R = InvalidReason;
  if (c.entity_id() == 0) return R::kZeroId;
  if (Find(c.entity_id()) != nullptr) return R::kDuplicateId;
  if (c.parent_id() != 0 && (c.parent_id() == c.entity_id() || Find(c.parent_id()) == nullptr)) {
    return R::kUnknownParent;
  }
  const float bound = config_.world_half_extent;
  if (const schema::Transform* t = c.transform()) {
    if (!Finite(t->position()) || !Finite(t->rotation()) || !Finite(t->scale())) return R::kNaN;
    if (!QuatUsable(t->rotation())) return R::kOutOfRange;
    const schema::Vec3& p = t->position();
    if (std::abs(p.x()) > bound || std::abs(p.y()) > bound || std::abs(p.z()) > bound) {
      return R::kOutOfRange;
    }
    const btVector3 s = ScaleOf(c);
    if (s.x() <= 0 || s.y() <= 0 || s.z() <= 0) return R::kOutOfRange;
  }
  const btVector3 scale = ScaleOf(c);

  if (const schema::SoftBody* sb = c.soft_body()) {
    if (!config_.soft_body_world) return R::kSoftBodiesDisabled;
    const auto* particles = sb->particles();
    if (particles == nullptr || particles->size() == 0 || particles->size() % 3 != 0) {
      return R::kBadSoftBody;
    }
    const size_t n = particles->size() / 3;
    if (n > config_.max_soft_nodes) return R::kTooManyNodes;
    for (float v : *particles) {
      if (!Finite(v)) return R::kNaN;
      if (std::abs(v) > bound) return R::kOutOfRange;
    }
    if (const auto* masses = sb->masses(); masses != nullptr && masses->size() != 0) {
      if (masses->size() != n) return R::kBadSoftBody;
      for (float m : *masses) {
        if (!Finite(m)) return R::kNaN;
        if (m < 0) return R::kNegativeMass;
      }
    }
    if (const auto* springs = sb->springs()) {
      if (springs->size() % 2 != 0) return R::kBadSoftBody;
      if (springs->size() / 2 > config_.max_soft_springs) return R::kTooManyNodes;
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

  const schema::RigidBody* rb = c.rigid_body();
  bool dynamic = false;
  if (rb != nullptr) {
    if (!Finite(rb->mass()) || !Finite(rb->linear_damping()) || !Finite(rb->angular_damping()) ||
        !Finite(rb->friction()) || !Finite(rb->restitution())) {
      return R::kNaN;
    }
    if (rb->linear_velocity() && !Finite(*rb->linear_velocity())) return R::kNaN;
    if (rb->angular_velocity() && !Finite(*rb->angular_velocity())) return R::kNaN;
    if (rb->mass() < 0) return R::kNegativeMass;
    if (rb->linear_damping() < 0 || rb->linear_damping() > 1 || rb->angular_damping() < 0 ||
        rb->angular_damping() > 1 || rb->friction() < 0 || rb->restitution() < 0 ||
        rb->restitution() > 1) {
      return R::kOutOfRange;
    }
    const bool kinematic =
        rb->kinematic() || (c.flags() & static_cast<uint32_t>(schema::EntityFlags::Kinematic));
    dynamic = !kinematic && rb->mass() > 0;
  }

  if (const auto* colliders = c.colliders()) {
    if (colliders->size() > config_.max_colliders) return R::kTooManyColliders;
    for (const schema::Collider* col : *colliders) {
      if (col->half_extents() && !Finite(*col->half_extents())) return R::kNaN;
      if (col->local_position() && !Finite(*col->local_position())) return R::kNaN;
      if (col->local_rotation() && !Finite(*col->local_rotation())) return R::kNaN;
      if (!Finite(col->radius()) || !Finite(col->height())) return R::kNaN;
      if (col->local_rotation() && !QuatUsable(*col->local_rotation())) return R::kOutOfRange;
      switch (col->shape()) {
        case schema::ColliderShape::Box:
        case schema::ColliderShape::Cylinder: {
          const schema::Vec3* he = col->half_extents();
          if (he == nullptr || he->x() <= 0 || he->y() <= 0 || he->z() <= 0) {
            return R::kOutOfRange;
          }
          break;
        }
        case schema::ColliderShape::Sphere:
          if (col->radius() <= 0) return R::kOutOfRange;
          break;
        case schema::ColliderShape::Capsule:
          if (col->radius() <= 0 || col->height() < 0) return R::kOutOfRange;
          break;
        case schema::ColliderShape::ConvexHull:
        case schema::ColliderShape::TriangleMesh: {
          const auto* v = col->vertices();
          if (v == nullptr || v->size() % 3 != 0) return R::kDegenerateMesh;
          const size_t nv = v->size() / 3;
          if (nv > config_.max_mesh_vertices) return R::kTooManyNodes;
          for (float f : *v) {
            if (!Finite(f)) return R::kNaN;
          }
          const bool hull = col->shape() == schema::ColliderShape::ConvexHull || dynamic;
          if (col->shape() == schema::ColliderShape::TriangleMesh) {
            const auto* idx = col->indices();
            if (nv < 3 || idx == nullptr || idx->size() < 3 || idx->size() % 3 != 0) {
              return R::kDegenerateMesh;
            }
            if (idx->size() / 3 > config_.max_mesh_triangles) return R::kTooManyNodes;
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
            if (!any_area) return R::kDegenerateMesh;
          }
          if (hull && (nv < 4 || !HullHasVolume(*v, scale))) return R::kDegenerateMesh;
          break;
        }
        default:
          return R::kUnknownShape;
      }
    }
  }

  if (const auto* joints = c.joints()) {
    if (joints->size() > config_.max_joints) return R::kTooManyColliders;
    for (const schema::Joint* j : *joints) {
      if (j->anchor() && !Finite(*j->anchor())) return R::kNaN;
      if (j->axis() && !Finite(*j->axis())) return R::kNaN;
      if (!Finite(j->stiffness()) || !Finite(j->damping())) return R::kNaN;
      if (j->kind() > schema::JointKind::MAX) return R::kUnknownShape;
      if (j->stiffness() < 0 || j->damping() < 0) return R::kOutOfRange;
      if (j->kind() == schema::JointKind::Hinge &&
          (j->axis() == nullptr || ToBt(*j->axis()).length2() < btScalar(1e-12))) {
        return R::kOutOfRange;
      }
      if (rb == nullptr || c.colliders() == nullptr || c.colliders()->size() == 0 ||
          (!dynamic && !rb->kinematic())) {
        return R::kBadJoint;
      }
      if (j->connected_entity() != 0) {
        const Entity* other = Find(j->connected_entity());
        if (j->connected_entity() == c.entity_id() || other == nullptr || !other->body) {
          return R::kUnknownJointTarget;
        }
      }
    }
  }
  return R::kNone;
}

// ---------------------------------------------------------------------------------------------
// Building

Status PhysicsWorld::AddEntity(const schema::Container& c, InvalidReason* reason) {
  const InvalidReason why = Validate(c);
  if (reason != nullptr) *reason = why;
  if (why != InvalidReason::kNone) {
    ++stats_.rejected_containers;
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

  auto owned = std::make_unique<Entity>();
  Entity* e = owned.get();
  e->id = c.entity_id();
  e->parent_id = c.parent_id();
  e->flags = c.flags();
  const btTransform xf = TransformOf(c);
  const btVector3 scale = ScaleOf(c);
  e->xf = xf;
  e->last_good = xf;
  if (e->parent_id != 0) {
    e->parent = Find(e->parent_id);
    e->parent->children.push_back(e);
    e->local = e->parent->CurrentTransform().inverse() * xf;
  }

  // Soft body.
  if (const schema::SoftBody* sb = c.soft_body()) {
    e->kind = Kind::kSoft;
    const auto& p = *sb->particles();
    const int n = static_cast<int>(p.size() / 3);
    std::vector<btVector3> x(n);
    std::vector<btScalar> m(n, btScalar(1.0) / btScalar(n));
    const auto* masses = sb->masses();
    btScalar mass_sum = 0;
    int mass_count = 0;
    btVector3 mn(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), mx = -mn;
    for (int i = 0; i < n; ++i) {
      x[i] = btVector3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
      mn.setMin(x[i]);
      mx.setMax(x[i]);
      if (masses != nullptr && masses->size() != 0) m[i] = masses->Get(i);
      if (m[i] > 0) mass_sum += m[i], ++mass_count;
    }
    e->soft = std::make_unique<btSoftBody>(soft_info_, n, x.data(), m.data());
    btSoftBody* s = e->soft.get();
    btSoftBody::Material* mat = s->m_materials[0];
    const btScalar mean_mass = mass_count > 0 ? mass_sum / mass_count : btScalar(1);
    // Bullet's position-based links act once per internal step (fixed_dt / substeps).
    const btScalar dt = config_.fixed_dt / static_cast<btScalar>(std::max(1, config_.substeps));
    btScalar klst = sb->stiffness() * dt * dt * btScalar(2) / mean_mass;
    klst = std::clamp(klst, btScalar(1e-4), btScalar(config_.soft_max_link_stiffness));
    mat->m_kLST = klst;
    mat->m_kAST = 0;
    if (const auto* springs = sb->springs()) {
      for (size_t i = 0; i < springs->size(); i += 2) {
        s->appendLink(static_cast<int>(springs->Get(i)), static_cast<int>(springs->Get(i + 1)),
                      mat, false);
      }
    }
    s->m_cfg.kDP = sb->damping();
    s->m_cfg.piterations = config_.soft_iterations;
    s->m_cfg.kDF = 0.5;
    // Contact hardness: the fraction of a node's penetration removed per solver iteration.
    // Bullet's default for static/kinematic partners (kKHR 0.1) lets a ~500-node lattice sink
    // ~11 cm into the ground; 1 removes it fully (rigid partners already use kCHR = 1).
    s->m_cfg.kKHR = 1;
    s->m_cfg.kCHR = 1;
    s->getCollisionShape()->setMargin(config_.soft_margin);
    s->setUserPointer(e);
    s->setUserIndex(kRoleBody);
    if (!config_.sleeping) s->setActivationState(DISABLE_DEACTIVATION);
    static_cast<btSoftRigidDynamicsWorld*>(world_.get())->addSoftBody(s);
    e->soft_good = x;
    e->soft_diag0 = std::max((mx - mn).length(), btScalar(0.1));
    soft_entities_.push_back(e);
    entities_.emplace(e->id, std::move(owned));
    return Status::Ok();
  }

  // Kind.
  const schema::RigidBody* rb = c.rigid_body();
  const bool kinematic =
      rb != nullptr &&
      (rb->kinematic() || (c.flags() & static_cast<uint32_t>(schema::EntityFlags::Kinematic)));
  const bool dynamic = rb != nullptr && !kinematic && rb->mass() > 0;
  const bool has_colliders = c.colliders() != nullptr && c.colliders()->size() != 0;
  if (dynamic) {
    e->kind = Kind::kDynamic;
  } else if (kinematic) {
    e->kind = Kind::kKinematic;
  } else if (has_colliders) {
    e->kind = Kind::kStatic;
  } else {
    e->kind = Kind::kTransformOnly;
  }

  // Shapes: solid colliders and trigger colliders.
  std::vector<std::pair<btTransform, btCollisionShape*>> solid, trig;
  const btScalar smax = std::max({scale.x(), scale.y(), scale.z()});
  if (has_colliders) {
    for (const schema::Collider* col : *c.colliders()) {
      btCollisionShape* shape = nullptr;
      const btVector3 he = col->half_extents() ? ToBt(*col->half_extents()) * scale : btVector3();
      switch (col->shape()) {
        case schema::ColliderShape::Box:
          shape = new btBoxShape(he);
          break;
        case schema::ColliderShape::Cylinder:
          shape = new btCylinderShape(he);
          break;
        case schema::ColliderShape::Sphere:
          shape = new btSphereShape(col->radius() * smax);
          break;
        case schema::ColliderShape::Capsule:
          shape = new btCapsuleShape(col->radius() * smax, col->height() * scale.y());
          break;
        case schema::ColliderShape::ConvexHull:
        case schema::ColliderShape::TriangleMesh: {
          const auto& v = *col->vertices();
          const size_t nv = v.size() / 3;
          if (col->shape() == schema::ColliderShape::ConvexHull || dynamic) {
            auto* hull = new btConvexHullShape();
            for (size_t i = 0; i < nv; ++i) {
              hull->addPoint(btVector3(v[3 * i], v[3 * i + 1], v[3 * i + 2]) * scale, false);
            }
            hull->recalcLocalAabb();
            hull->setMargin(btScalar(0.005));
            shape = hull;
          } else {
            auto mesh = std::make_unique<MeshData>();
            mesh->vertices.resize(v.size());
            for (size_t i = 0; i < nv; ++i) {
              const btVector3 s = btVector3(v[3 * i], v[3 * i + 1], v[3 * i + 2]) * scale;
              mesh->vertices[3 * i] = s.x();
              mesh->vertices[3 * i + 1] = s.y();
              mesh->vertices[3 * i + 2] = s.z();
            }
            const auto& idx = *col->indices();
            mesh->indices.assign(idx.begin(), idx.end());
            mesh->array = std::make_unique<btTriangleIndexVertexArray>(
                static_cast<int>(mesh->indices.size() / 3), mesh->indices.data(),
                static_cast<int>(3 * sizeof(int)), static_cast<int>(nv), mesh->vertices.data(),
                static_cast<int>(3 * sizeof(btScalar)));
            auto* tri = new btBvhTriangleMeshShape(mesh->array.get(), true, true);
            tri->setMargin(btScalar(0.005));
            shape = tri;
            e->meshes.push_back(std::move(mesh));
          }
          break;
        }
        default:
          break;  // unreachable: validated
      }
      e->shapes.emplace_back(shape);
      btQuaternion lr = col->local_rotation() ? ToBt(*col->local_rotation())
                                              : btQuaternion::getIdentity();
      btVector3 lp = col->local_position() ? ToBt(*col->local_position()) * scale : btVector3();
      (col->is_trigger() ? trig : solid).emplace_back(btTransform(lr, lp), shape);
    }
  }
  auto make_root = [&](std::vector<std::pair<btTransform, btCollisionShape*>>& parts)
      -> btCollisionShape* {
    if (parts.empty()) return nullptr;
    if (parts.size() == 1 && parts[0].first.getOrigin().isZero() &&
        parts[0].first.getRotation() == btQuaternion::getIdentity()) {
      return parts[0].second;
    }
    auto* compound = new btCompoundShape(true, static_cast<int>(parts.size()));
    for (auto& [t, s] : parts) compound->addChildShape(t, s);
    e->shapes.emplace_back(compound);
    return compound;
  };
  btCollisionShape* solid_root = make_root(solid);
  btCollisionShape* trigger_root = make_root(trig);

  btCollisionShape* body_shape = solid_root;
  bool body_is_trigger = false;
  bool body_collides_nothing = false;
  if (dynamic && body_shape == nullptr) {
    if (trigger_root != nullptr) {
      body_shape = trigger_root;  // a dynamic trigger: the body itself does not respond
      trigger_root = nullptr;
      body_is_trigger = true;
    } else {
      auto* placeholder = new btSphereShape(btScalar(0.1) * smax);
      e->shapes.emplace_back(placeholder);
      body_shape = placeholder;
      body_collides_nothing = true;
    }
  }

  if (body_shape != nullptr) {
    const btScalar mass = dynamic ? rb->mass() : btScalar(0);
    btVector3 inertia(0, 0, 0);
    if (dynamic) body_shape->calculateLocalInertia(mass, inertia);
    e->motion = std::make_unique<EntityMotionState>(this, e, xf);
    btRigidBody::btRigidBodyConstructionInfo ci(mass, e->motion.get(), body_shape, inertia);
    if (rb != nullptr) {
      ci.m_friction = rb->friction();
      ci.m_restitution = rb->restitution();
      ci.m_linearDamping = rb->linear_damping();
      ci.m_angularDamping = rb->angular_damping();
    } else {
      ci.m_friction = 0.5;
    }
    ci.m_linearSleepingThreshold = config_.sleep_linear_threshold;
    ci.m_angularSleepingThreshold = config_.sleep_angular_threshold;
    e->body = std::make_unique<btRigidBody>(ci);
    btRigidBody* body = e->body.get();
    body->setUserPointer(e);
    body->setUserIndex(kRoleBody);
    if (body_is_trigger) {
      body->setCollisionFlags(body->getCollisionFlags() |
                              btCollisionObject::CF_NO_CONTACT_RESPONSE);
    }
    if (kinematic) {
      body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
      body->setActivationState(DISABLE_DEACTIVATION);
    }
    if (dynamic) {
      if (!config_.sleeping) body->setActivationState(DISABLE_DEACTIVATION);
      btVector3 center;
      btScalar bound_radius;
      body_shape->getBoundingSphere(center, bound_radius);
      e->radius = bound_radius + center.length();
      if (config_.ccd) {
        btVector3 mn, mx;
        body_shape->getAabb(btTransform::getIdentity(), mn, mx);
        const btVector3 half = (mx - mn) * btScalar(0.5);
        const btScalar inner = std::min({half.x(), half.y(), half.z()});
        body->setCcdMotionThreshold(inner * config_.ccd_motion_fraction);
        body->setCcdSweptSphereRadius(inner * config_.ccd_swept_radius_fraction);
      }
      if (rb->linear_velocity()) body->setLinearVelocity(ToBt(*rb->linear_velocity()));
      if (rb->angular_velocity()) body->setAngularVelocity(ToBt(*rb->angular_velocity()));
    }
    if (body_collides_nothing) {
      world_->addRigidBody(body, btBroadphaseProxy::DefaultFilter, 0);
    } else {
      world_->addRigidBody(body);
    }
    if (dynamic) {
      if (!rb->use_gravity()) {
        body->setFlags(body->getFlags() | BT_DISABLE_WORLD_GRAVITY);
        body->setGravity(btVector3(0, 0, 0));
      }
      e->gravity = body->getGravity();
      ++dynamic_bodies_;
    }
    ++bodies_;
  }

  if (trigger_root != nullptr) {
    e->trigger = std::make_unique<btCollisionObject>();
    btCollisionObject* t = e->trigger.get();
    t->setCollisionShape(trigger_root);
    t->setWorldTransform(xf);
    t->setCollisionFlags(btCollisionObject::CF_NO_CONTACT_RESPONSE);
    t->setUserPointer(e);
    t->setUserIndex(kRoleTrigger);
    t->setActivationState(DISABLE_DEACTIVATION);
    if (e->body) t->setIgnoreCollisionCheck(e->body.get(), true);
    world_->addCollisionObject(
        t, btBroadphaseProxy::SensorTrigger,
        btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::SensorTrigger ^
            btBroadphaseProxy::StaticFilter);
    if (e->kind == Kind::kDynamic || e->kind == Kind::kKinematic) {
      trigger_followers_.push_back(e);
    }
  }

  // Joints.
  if (const auto* joints = c.joints()) {
    for (const schema::Joint* j : *joints) {
      Entity* other = j->connected_entity() != 0 ? Find(j->connected_entity()) : nullptr;
      btRigidBody& body_a = *e->body;
      btRigidBody& body_b = other != nullptr ? *other->body : *fixed_body_;
      const btTransform world_b =
          other != nullptr ? other->body->getWorldTransform() : btTransform::getIdentity();
      const btVector3 anchor = j->anchor() ? ToBt(*j->anchor()) * scale : btVector3();
      btVector3 axis = j->axis() ? ToBt(*j->axis()) : btVector3(0, 0, 1);
      if (axis.length2() < btScalar(1e-12)) axis = btVector3(0, 0, 1);
      axis.normalize();
      const btTransform frame_a = FrameWithZ(anchor, axis);
      const btTransform frame_b = world_b.inverse() * xf * frame_a;
      std::unique_ptr<btTypedConstraint> constraint;
      switch (j->kind()) {
        case schema::JointKind::Fixed:
          constraint = std::make_unique<btFixedConstraint>(body_a, body_b, frame_a, frame_b);
          break;
        case schema::JointKind::Hinge:
          constraint = std::make_unique<btHingeConstraint>(body_a, body_b, frame_a, frame_b);
          break;
        case schema::JointKind::Spring: {
          auto spring = std::make_unique<btGeneric6DofSpring2Constraint>(body_a, body_b, frame_a,
                                                                        frame_b);
          spring->setLinearLowerLimit(btVector3(1, 1, 1));  // lower > upper: free
          spring->setLinearUpperLimit(btVector3(-1, -1, -1));
          spring->setAngularLowerLimit(btVector3(1, 1, 1));
          spring->setAngularUpperLimit(btVector3(-1, -1, -1));
          for (int i = 0; i < 3; ++i) {
            spring->enableSpring(i, true);
            spring->setStiffness(i, j->stiffness());
            spring->setDamping(i, j->damping());
          }
          spring->setEquilibriumPoint();
          constraint = std::move(spring);
          break;
        }
        default:
          break;
      }
      if (!constraint) continue;
      world_->addConstraint(constraint.get(), true);
      auto rec = std::make_unique<JointRecord>();
      rec->owner = e->id;
      rec->other = other != nullptr ? other->id : 0;
      rec->constraint = std::move(constraint);
      joints_.push_back(std::move(rec));
    }
  }

  entities_.emplace(e->id, std::move(owned));
  return Status::Ok();
}

void PhysicsWorld::RemoveJointsOf(uint32_t id) {
  for (size_t i = 0; i < joints_.size();) {
    if (joints_[i]->owner == id || joints_[i]->other == id) {
      world_->removeConstraint(joints_[i]->constraint.get());
      joints_[i] = std::move(joints_.back());
      joints_.pop_back();
    } else {
      ++i;
    }
  }
}

Status PhysicsWorld::RemoveEntity(uint32_t id) {
  Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (e->grabbed) (void)Release(id);
  for (size_t i = 0; i < grabbed_.size();) {
    if (grabbed_[i]->grabbed_by == id) {
      const size_t before = grabbed_.size();
      (void)Release(grabbed_[i]->id);
      if (grabbed_.size() == before) ++i;
    } else {
      ++i;
    }
  }
  RemoveJointsOf(id);
  std::erase(dirty_, e);
  std::erase(stepped_, e);
  std::erase(pending_moves_, e);
  std::erase(moving_, e);
  std::erase(trigger_followers_, e);
  std::erase(soft_entities_, e);
  for (Entity* child : e->children) {
    child->parent = nullptr;
    child->parent_id = 0;
  }
  if (e->parent != nullptr) std::erase(e->parent->children, e);
  if (e->body) {
    world_->removeRigidBody(e->body.get());
    --bodies_;
    if (e->kind == Kind::kDynamic) --dynamic_bodies_;
  }
  if (e->trigger) world_->removeCollisionObject(e->trigger.get());
  if (e->soft) static_cast<btSoftRigidDynamicsWorld*>(world_.get())->removeSoftBody(e->soft.get());
  entities_.erase(id);
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Commands

Status PhysicsWorld::MoveToTransform(uint32_t id, const Vec3f& pos, const Quatf& rot) {
  Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (!Finite(pos) || !Finite(rot)) return Status(StatusCode::kInvalidArgument, "non-finite pose");
  const btTransform t(ToBt(rot), ToBt(pos));
  switch (e->kind) {
    case Kind::kKinematic:
      if (e->body) {
        e->target = t;
        e->has_target = true;
        if (!e->pending_move) {
          e->pending_move = true;
          pending_moves_.push_back(e);
        }
        return Status::Ok();
      }
      return SetTransform(id, pos, rot);
    case Kind::kDynamic:
      if (!e->grabbed) return Status(StatusCode::kInvalidArgument, "dynamic entity not grabbed");
      e->target = t;
      e->has_target = true;
      return Status::Ok();
    case Kind::kSoft:
      return Status(StatusCode::kInvalidArgument, "soft bodies cannot be moved");
    default:
      return SetTransform(id, pos, rot);
  }
}

Status PhysicsWorld::SetTransform(uint32_t id, const Vec3f& pos, const Quatf& rot) {
  Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (!Finite(pos) || !Finite(rot)) return Status(StatusCode::kInvalidArgument, "non-finite pose");
  if (e->kind == Kind::kSoft) return Status(StatusCode::kInvalidArgument, "soft body");
  const btTransform t(ToBt(rot), ToBt(pos));
  if (e->body) {
    btRigidBody* body = e->body.get();
    body->setWorldTransform(t);
    body->setInterpolationWorldTransform(t);
    e->motion->transform() = t;
    e->last_good = t;
    if (e->kind == Kind::kKinematic) {
      e->target = t;
      e->has_target = false;
      if (e->pending_move) {
        e->pending_move = false;
        std::erase(pending_moves_, e);
      }
    }
    if (e->kind == Kind::kDynamic) body->activate(true);
    world_->updateSingleAabb(body);
  } else {
    e->xf = t;
  }
  if (e->trigger) {
    e->trigger->setWorldTransform(t);
    world_->updateSingleAabb(e->trigger.get());
  }
  if (e->parent != nullptr && e->kind == Kind::kTransformOnly) {
    e->local = e->parent->CurrentTransform().inverse() * t;
  }
  MarkDirty(e);
  return Status::Ok();
}

Status PhysicsWorld::Grab(uint32_t entity, uint32_t hand_entity) {
  Entity* e = Find(entity);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (e->kind != Kind::kDynamic) return Status(StatusCode::kInvalidArgument, "not dynamic");
  if (!(e->flags & static_cast<uint32_t>(schema::EntityFlags::Interactable))) {
    return Status(StatusCode::kPermissionDenied, "not interactable");
  }
  if (hand_entity != 0 && Find(hand_entity) == nullptr) {
    return Status(StatusCode::kNotFound, "unknown hand");
  }
  e->grabbed_by = hand_entity;
  if (e->grabbed) return Status::Ok();
  e->grabbed = true;
  e->target = e->body->getWorldTransform();
  e->has_target = true;
  e->body->setGravity(btVector3(0, 0, 0));
  e->body->setActivationState(DISABLE_DEACTIVATION);
  grabbed_.push_back(e);
  return Status::Ok();
}

Status PhysicsWorld::Release(uint32_t entity) {
  Entity* e = Find(entity);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (!e->grabbed) return Status(StatusCode::kInvalidArgument, "not grabbed");
  e->grabbed = false;
  e->grabbed_by = 0;
  e->has_target = false;
  e->body->setGravity(e->gravity);
  e->body->forceActivationState(config_.sleeping ? ACTIVE_TAG : DISABLE_DEACTIVATION);
  e->body->activate(true);
  std::erase(grabbed_, e);
  return Status::Ok();
}

bool PhysicsWorld::IsGrabbed(uint32_t entity) const {
  const Entity* e = Find(entity);
  return e != nullptr && e->grabbed;
}

Status PhysicsWorld::SetVelocity(uint32_t id, const Vec3f& linear, const Vec3f& angular) {
  Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  if (!Finite(linear) || !Finite(angular)) {
    return Status(StatusCode::kInvalidArgument, "non-finite velocity");
  }
  if (e->kind == Kind::kSoft) {
    e->soft->setVelocity(ToBt(linear));
    e->soft->activate(true);
    return Status::Ok();
  }
  if (e->kind != Kind::kDynamic) return Status(StatusCode::kInvalidArgument, "not dynamic");
  e->body->setLinearVelocity(ToBt(linear));
  e->body->setAngularVelocity(ToBt(angular));
  e->body->activate(true);
  return Status::Ok();
}

Status PhysicsWorld::GetVelocity(uint32_t id, Vec3f* linear, Vec3f* angular) const {
  const Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  Vec3f lin, ang;
  if (e->body && e->kind == Kind::kDynamic) {
    lin = ToVec(e->body->getLinearVelocity());
    ang = ToVec(e->body->getAngularVelocity());
  } else if (e->body && e->kind == Kind::kKinematic) {
    lin = ToVec(e->body->getInterpolationLinearVelocity());
    ang = ToVec(e->body->getInterpolationAngularVelocity());
  }
  if (linear != nullptr) *linear = lin;
  if (angular != nullptr) *angular = ang;
  return Status::Ok();
}

Status PhysicsWorld::GetState(uint32_t id, EntityState* state) const {
  const Entity* e = Find(id);
  if (e == nullptr) return Status(StatusCode::kNotFound, "unknown entity");
  *state = ToState(id, e->CurrentTransform());
  return Status::Ok();
}

Status PhysicsWorld::GetSoftBodyNodes(uint32_t id, std::vector<Vec3f>* out) const {
  const Entity* e = Find(id);
  if (e == nullptr || !e->soft) return Status(StatusCode::kNotFound, "no such soft body");
  const auto& nodes = e->soft->m_nodes;
  out->resize(static_cast<size_t>(nodes.size()));
  for (int i = 0; i < nodes.size(); ++i) (*out)[i] = ToVec(nodes[i].m_x);
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Stepping

void PhysicsWorld::ApplyCommands() {
  moving_.clear();
  for (Entity* e : pending_moves_) {
    e->pending_move = false;
    e->move_from = e->motion->transform();
    moving_.push_back(e);
    e->motion->transform() = e->target;  // Bullet reads it in saveKinematicState
    e->last_good = e->target;
    MarkDirty(e);
  }
  pending_moves_.clear();

  const btScalar dt = config_.fixed_dt;
  for (Entity* e : grabbed_) {
    if (!e->has_target) continue;
    btRigidBody* body = e->body.get();
    const btTransform& cur = body->getWorldTransform();
    btVector3 v = (e->target.getOrigin() - cur.getOrigin()) * (config_.grab_gain / dt);
    const btScalar vmax = config_.grab_max_speed;
    if (v.length2() > vmax * vmax) v *= vmax / v.length();
    btQuaternion dq = e->target.getRotation() * cur.getRotation().inverse();
    if (dq.w() < 0) dq = -dq;
    btVector3 w(0, 0, 0);
    const btScalar angle = dq.getAngle();
    if (angle > btScalar(1e-6)) {
      w = dq.getAxis() * (angle * config_.grab_gain / dt);
      const btScalar wmax = config_.grab_max_angular_speed;
      if (w.length2() > wmax * wmax) w *= wmax / w.length();
    }
    body->setLinearVelocity(v);
    body->setAngularVelocity(w);
    body->activate(true);
  }

  for (Entity* e : trigger_followers_) {
    const btTransform& t = e->body ? (e->kind == Kind::kKinematic ? e->motion->transform()
                                                                  : e->body->getWorldTransform())
                                   : e->xf;
    e->trigger->setWorldTransform(t);
  }
}

void PhysicsWorld::Step() {
  ApplyCommands();
  stepped_.clear();
  // maxSubSteps = 0: exactly one internal step of h per call, no interpolation of motion states
  // (Bullet's own accumulator could run 3 or 5 steps through float rounding of dt / h).
  const int n = std::max(1, config_.substeps);
  const btScalar h = config_.fixed_dt / static_cast<btScalar>(n);
  for (int k = 1; k <= n; ++k) {
    if (n > 1) {
      // Kinematic bodies move along the straight line to their target, so their velocity (Bullet
      // derives it from the displacement per internal step) is the same in every substep.
      const btScalar f = static_cast<btScalar>(k) / static_cast<btScalar>(n);
      for (Entity* e : moving_) {
        btTransform& t = e->motion->transform();
        if (k == n) {
          t = e->target;
        } else {
          t.setOrigin(e->move_from.getOrigin().lerp(e->target.getOrigin(), f));
          t.setRotation(e->move_from.getRotation().slerp(e->target.getRotation(), f));
        }
      }
    }
    world_->stepSimulation(h, 0, h);
  }
  moving_.clear();
  ++stats_.steps;
  RunGuard();
  DiffContacts();
}

int PhysicsWorld::Advance(double elapsed_seconds) {
  if (!(elapsed_seconds > 0)) return 0;
  accumulator_ += elapsed_seconds;
  int n = 0;
  while (accumulator_ >= config_.fixed_dt && n < config_.max_substeps) {
    Step();
    accumulator_ -= config_.fixed_dt;
    ++n;
  }
  if (accumulator_ >= config_.fixed_dt) accumulator_ = 0;  // drop the backlog
  return n;
}

void PhysicsWorld::ResetRigid(Entity* e, GuardCause cause) {
  btRigidBody* body = e->body.get();
  body->setWorldTransform(e->last_good);
  body->setInterpolationWorldTransform(e->last_good);
  e->motion->transform() = e->last_good;
  const btVector3 zero(0, 0, 0);
  body->setLinearVelocity(zero);
  body->setAngularVelocity(zero);
  body->setInterpolationLinearVelocity(zero);
  body->setInterpolationAngularVelocity(zero);
  body->clearForces();
  if (cause == GuardCause::kOutOfBounds && !e->grabbed) {
    body->forceActivationState(ISLAND_SLEEPING);  // parked until something touches it
  } else {
    body->forceActivationState(e->grabbed || !config_.sleeping ? DISABLE_DEACTIVATION
                                                               : ACTIVE_TAG);
    body->setDeactivationTime(0);
  }
  world_->updateSingleAabb(body);
  ++stats_.guard_resets;
  PushEvent(PhysicsEvent{PhysicsEventType::kGuardReset, cause, e->id, 0, stats_.steps});
}

void PhysicsWorld::RunGuard() {
  const btScalar max_v2 = config_.max_linear_speed * config_.max_linear_speed;
  const btScalar max_w2 = config_.max_angular_speed * config_.max_angular_speed;
  const btScalar bound = config_.world_half_extent;
  for (Entity* e : stepped_) {
    e->in_stepped = false;
    btRigidBody* body = e->body.get();
    const btTransform& t = body->getWorldTransform();
    const btVector3& v = body->getLinearVelocity();
    const btVector3& w = body->getAngularVelocity();
    GuardCause cause = GuardCause::kNone;
    if (!Finite(t) || !Finite(v) || !Finite(w)) {
      cause = GuardCause::kNonFinite;
    } else if (v.length2() > max_v2 || w.length2() > max_w2) {
      cause = GuardCause::kRunawaySpeed;
    } else {
      const btVector3& o = t.getOrigin();
      const btScalar lim = bound - e->radius;
      if (std::abs(o.x()) > lim || std::abs(o.y()) > lim || std::abs(o.z()) > lim) {
        cause = GuardCause::kOutOfBounds;
      }
    }
    if (cause == GuardCause::kNone) {
      e->last_good = t;
    } else {
      ResetRigid(e, cause);
    }
    MarkDirty(e);
  }
  last_active_ = stepped_.size();
  stepped_.clear();
  for (Entity* e : soft_entities_) {
    if (!e->soft->isActive()) continue;
    RunSoftGuard(e);
    MarkDirty(e);
  }
}

void PhysicsWorld::RunSoftGuard(Entity* e) {
  btSoftBody* s = e->soft.get();
  btSoftBody::tNodeArray& nodes = s->m_nodes;
  const int n = nodes.size();
  btVector3 mn(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), mx = -mn;
  btScalar max_v2 = 0;
  bool finite = true;
  for (int i = 0; i < n; ++i) {
    const btSoftBody::Node& node = nodes[i];
    finite = finite && Finite(node.m_x) && Finite(node.m_v);
    mn.setMin(node.m_x);
    mx.setMax(node.m_x);
    max_v2 = std::max(max_v2, node.m_v.length2());
  }
  GuardCause cause = GuardCause::kNone;
  const btScalar bound = config_.world_half_extent;
  if (!finite) {
    cause = GuardCause::kNonFinite;
  } else if (max_v2 > config_.soft_max_node_speed * config_.soft_max_node_speed ||
             (mx - mn).length() > e->soft_diag0 * config_.soft_max_extent_ratio) {
    cause = GuardCause::kSoftBodyExploded;
  } else if (mn.x() < -bound || mn.y() < -bound || mn.z() < -bound || mx.x() > bound ||
             mx.y() > bound || mx.z() > bound) {
    cause = GuardCause::kOutOfBounds;
  }
  if (cause == GuardCause::kNone) {
    for (int i = 0; i < n; ++i) e->soft_good[i] = nodes[i].m_x;
    e->soft_consecutive_resets = 0;
    return;
  }
  const btVector3 zero(0, 0, 0);
  for (int i = 0; i < n; ++i) {
    btSoftBody::Node& node = nodes[i];
    node.m_x = node.m_q = e->soft_good[i];
    node.m_v = zero;
    node.m_f = zero;
  }
  s->updateBounds();
  ++e->soft_consecutive_resets;
  if (e->soft_consecutive_resets >= config_.soft_soften_after_resets) {
    bool softened = false;
    for (int i = 0; i < s->m_materials.size(); ++i) {
      if (s->m_materials[i]->m_kLST > btScalar(1)) {
        s->m_materials[i]->m_kLST = 1;
        softened = true;
      }
    }
    if (softened) {
      s->m_bUpdateRtCst = true;
      ++stats_.soft_softened;
    }
  }
  ++stats_.guard_resets;
  PushEvent(PhysicsEvent{PhysicsEventType::kGuardReset, cause, e->id, 0, stats_.steps});
}

void PhysicsWorld::DiffContacts() {
  new_pairs_.clear();
  const int manifolds = dispatcher_->getNumManifolds();
  const btScalar touch = config_.contact_distance;
  for (int i = 0; i < manifolds; ++i) {
    const btPersistentManifold* m = dispatcher_->getManifoldByIndexInternal(i);
    const int contacts = m->getNumContacts();
    bool touching = false;
    for (int k = 0; k < contacts && !touching; ++k) {
      touching = m->getContactPoint(k).getDistance() <= touch;
    }
    if (!touching) continue;
    const btCollisionObject* o0 = m->getBody0();
    const btCollisionObject* o1 = m->getBody1();
    const auto* e0 = static_cast<const Entity*>(o0->getUserPointer());
    const auto* e1 = static_cast<const Entity*>(o1->getUserPointer());
    if (e0 == nullptr || e1 == nullptr || e0 == e1) continue;
    const bool t0 = !o0->hasContactResponse();
    const bool t1 = !o1->hasContactResponse();
    if (t0 && t1) continue;
    PairKey key;
    if (t0 || t1) {
      key.a = t0 ? e0->id : e1->id;
      key.b = t0 ? e1->id : e0->id;
      key.trigger = 1;
    } else {
      key.a = std::min(e0->id, e1->id);
      key.b = std::max(e0->id, e1->id);
    }
    new_pairs_.push_back(key);
  }
  std::sort(new_pairs_.begin(), new_pairs_.end());
  new_pairs_.erase(std::unique(new_pairs_.begin(), new_pairs_.end()), new_pairs_.end());

  // Merge-diff against the previous step's pairs: deterministic, sorted by pair.
  size_t i = 0, j = 0;
  const uint64_t step = stats_.steps;
  auto emit = [&](const PairKey& k, bool enter) {
    PhysicsEventType type;
    if (k.trigger) {
      type = enter ? PhysicsEventType::kTriggerEnter : PhysicsEventType::kTriggerExit;
    } else {
      type = enter ? PhysicsEventType::kCollisionEnter : PhysicsEventType::kCollisionExit;
    }
    PushEvent(PhysicsEvent{type, GuardCause::kNone, k.a, k.b, step});
  };
  while (i < pairs_.size() || j < new_pairs_.size()) {
    if (j == new_pairs_.size() || (i < pairs_.size() && pairs_[i] < new_pairs_[j])) {
      emit(pairs_[i++], false);
    } else if (i == pairs_.size() || new_pairs_[j] < pairs_[i]) {
      emit(new_pairs_[j++], true);
    } else {
      ++i, ++j;
    }
  }
  pairs_.swap(new_pairs_);
}

// ---------------------------------------------------------------------------------------------
// Output

void PhysicsWorld::ReportTree(Entity* e, std::vector<EntityState>* moved) {
  const btTransform t = e->CurrentTransform();
  const EntityState s = ToState(e->id, t);
  if (e->has_reported && SameState(s, e->reported)) return;
  e->reported = s;
  e->has_reported = true;
  moved->push_back(s);
  for (Entity* child : e->children) {
    if (child->kind != Kind::kTransformOnly) continue;
    child->xf = t * child->local;
    ReportTree(child, moved);
  }
}

void PhysicsWorld::CollectStates(std::vector<EntityState>* moved) {
  moved->clear();
  for (Entity* e : dirty_) {
    e->in_dirty = false;
    ReportTree(e, moved);
  }
  dirty_.clear();
}

void PhysicsWorld::DrainEvents(std::vector<PhysicsEvent>* out) {
  out->insert(out->end(), events_.begin(), events_.end());
  events_.clear();
}

PhysicsCounters PhysicsWorld::counters() const {
  PhysicsCounters c = stats_;
  c.entities = entities_.size();
  c.bodies = bodies_;
  c.dynamic_bodies = dynamic_bodies_;
  c.sleeping_bodies =
      stats_.steps == 0 || last_active_ >= dynamic_bodies_ ? 0 : dynamic_bodies_ - last_active_;
  c.soft_bodies = soft_entities_.size();
  c.joints = joints_.size();
  return c;
}

void PhysicsWorld::EntityIds(std::vector<uint32_t>* ids) const {
  ids->clear();
  ids->reserve(entities_.size());
  for (const auto& [id, e] : entities_) ids->push_back(id);
  std::sort(ids->begin(), ids->end());
}

btRigidBody* PhysicsWorld::RigidBodyForTesting(uint32_t id) const {
  const Entity* e = Find(id);
  return e != nullptr ? e->body.get() : nullptr;
}

btSoftBody* PhysicsWorld::SoftBodyForTesting(uint32_t id) const {
  const Entity* e = Find(id);
  return e != nullptr ? e->soft.get() : nullptr;
}

}  // namespace edgephys::physics
