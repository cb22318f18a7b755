// AddEntity's build steps: Bullet objects from a validated container (the builder contract is
// in physics_world.h). Every step assumes ValidateContainer() accepted the container, so none
// of them fails.
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <algorithm>

#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {
namespace {

using internal::BodyShapes;
using internal::Kind;
using internal::kRoleBody;
using internal::kRoleTrigger;
using internal::ToBt;

// (local pose, shape) of each collider of one kind (solid or trigger).
using ShapeParts = std::vector<std::pair<btTransform, btCollisionShape*>>;

// Hull margin; also the triangle-mesh margin (m).
constexpr btScalar kMeshMargin = btScalar(0.005);

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

Kind KindOf(const schema::Container& c) {
  const bool has_colliders = c.colliders() != nullptr && c.colliders()->size() != 0;
  if (internal::IsDynamic(c)) return Kind::kDynamic;
  if (internal::IsKinematic(c)) return Kind::kKinematic;
  if (has_colliders) return Kind::kStatic;
  return Kind::kTransformOnly;
}

// --- Shapes

btCollisionShape* BuildHull(const flatbuffers::Vector<float>& v, const btVector3& scale) {
  const size_t nv = v.size() / 3;
  auto* hull = new btConvexHullShape();
  for (size_t i = 0; i < nv; ++i) {
    hull->addPoint(btVector3(v[3 * i], v[3 * i + 1], v[3 * i + 2]) * scale, false);
  }
  hull->recalcLocalAabb();
  hull->setMargin(kMeshMargin);
  return hull;
}

// An exact (BVH) triangle mesh; `e` keeps the vertex and index arrays it references.
btCollisionShape* BuildTriangleMesh(const schema::Collider& col, const btVector3& scale,
                                    PhysicsWorld::Entity* e) {
  const auto& v = *col.vertices();
  const size_t nv = v.size() / 3;
  auto mesh = std::make_unique<MeshData>();
  mesh->vertices.resize(v.size());
  for (size_t i = 0; i < nv; ++i) {
    const btVector3 s = btVector3(v[3 * i], v[3 * i + 1], v[3 * i + 2]) * scale;
    mesh->vertices[3 * i] = s.x();
    mesh->vertices[3 * i + 1] = s.y();
    mesh->vertices[3 * i + 2] = s.z();
  }
  const auto& idx = *col.indices();
  mesh->indices.assign(idx.begin(), idx.end());
  mesh->array = std::make_unique<btTriangleIndexVertexArray>(
      static_cast<int>(mesh->indices.size() / 3), mesh->indices.data(),
      static_cast<int>(3 * sizeof(int)), static_cast<int>(nv), mesh->vertices.data(),
      static_cast<int>(3 * sizeof(btScalar)));
  auto* tri = new btBvhTriangleMeshShape(mesh->array.get(), true, true);
  tri->setMargin(kMeshMargin);
  e->meshes.push_back(std::move(mesh));
  return tri;
}

// One collider's shape, scaled; triangle meshes on dynamic entities become hulls. The caller
// takes ownership.
btCollisionShape* BuildColliderShape(const schema::Collider& col, const btVector3& scale,
                                     bool dynamic, PhysicsWorld::Entity* e) {
  const btScalar smax = std::max({scale.x(), scale.y(), scale.z()});
  const btVector3 he = col.half_extents() ? ToBt(*col.half_extents()) * scale : btVector3();
  switch (col.shape()) {
    case schema::ColliderShape::Box:
      return new btBoxShape(he);
    case schema::ColliderShape::Cylinder:
      return new btCylinderShape(he);
    case schema::ColliderShape::Sphere:
      return new btSphereShape(col.radius() * smax);
    case schema::ColliderShape::Capsule:
      return new btCapsuleShape(col.radius() * smax, col.height() * scale.y());
    case schema::ColliderShape::ConvexHull:
      return BuildHull(*col.vertices(), scale);
    case schema::ColliderShape::TriangleMesh:
      return dynamic ? BuildHull(*col.vertices(), scale) : BuildTriangleMesh(col, scale, e);
    default:
      return nullptr;  // unreachable: validated
  }
}

// The single part itself if it sits at the origin unrotated, otherwise a compound of all parts
// (owned by `e`); nullptr without parts.
btCollisionShape* MakeRootShape(const ShapeParts& parts, PhysicsWorld::Entity* e) {
  if (parts.empty()) return nullptr;
  if (parts.size() == 1 && parts[0].first.getOrigin().isZero() &&
      parts[0].first.getRotation() == btQuaternion::getIdentity()) {
    return parts[0].second;
  }
  auto* compound = new btCompoundShape(true, static_cast<int>(parts.size()));
  for (const auto& [t, s] : parts) compound->addChildShape(t, s);
  e->shapes.emplace_back(compound);
  return compound;
}

// Solid and trigger shapes of a (non-soft) container, and which of them the rigid body uses.
// `e` owns every shape built.
BodyShapes BuildShapes(const schema::Container& c, bool dynamic, PhysicsWorld::Entity* e) {
  const btVector3 scale = internal::ScaleOf(c);
  ShapeParts solid, trig;
  if (c.colliders() != nullptr) {
    for (const schema::Collider* col : *c.colliders()) {
      btCollisionShape* shape = BuildColliderShape(*col, scale, dynamic, e);
      e->shapes.emplace_back(shape);
      btQuaternion lr =
          col->local_rotation() ? ToBt(*col->local_rotation()) : btQuaternion::getIdentity();
      btVector3 lp = col->local_position() ? ToBt(*col->local_position()) * scale : btVector3();
      (col->is_trigger() ? trig : solid).emplace_back(btTransform(lr, lp), shape);
    }
  }
  BodyShapes out;
  out.body = MakeRootShape(solid, e);
  out.trigger = MakeRootShape(trig, e);
  if (dynamic && out.body == nullptr) {
    if (out.trigger != nullptr) {
      out.body = out.trigger;  // a dynamic trigger: the body itself does not respond
      out.trigger = nullptr;
      out.body_is_trigger = true;
    } else {
      const btScalar smax = std::max({scale.x(), scale.y(), scale.z()});
      auto* placeholder = new btSphereShape(btScalar(0.1) * smax);
      e->shapes.emplace_back(placeholder);
      out.body = placeholder;
      out.body_collides_nothing = true;
    }
  }
  return out;
}

// --- Rigid body

btRigidBody::btRigidBodyConstructionInfo BodyInfo(const schema::RigidBody* rb, bool dynamic,
                                                  btMotionState* motion, btCollisionShape* shape,
                                                  const PhysicsConfig& config) {
  const btScalar mass = dynamic ? rb->mass() : btScalar(0);
  btVector3 inertia(0, 0, 0);
  if (dynamic) shape->calculateLocalInertia(mass, inertia);
  btRigidBody::btRigidBodyConstructionInfo ci(mass, motion, shape, inertia);
  if (rb != nullptr) {
    ci.m_friction = rb->friction();
    ci.m_restitution = rb->restitution();
    ci.m_linearDamping = rb->linear_damping();
    ci.m_angularDamping = rb->angular_damping();
  } else {
    ci.m_friction = 0.5;
  }
  ci.m_linearSleepingThreshold = config.sleep_linear_threshold;
  ci.m_angularSleepingThreshold = config.sleep_angular_threshold;
  return ci;
}

// Dynamic bodies: sleeping, bounding radius (bounds check), CCD, initial velocities.
void ConfigureDynamic(btRigidBody* body, const schema::RigidBody& rb, btCollisionShape* shape,
                      const PhysicsConfig& config, PhysicsWorld::Entity* e) {
  if (!config.sleeping) body->setActivationState(DISABLE_DEACTIVATION);
  body->setContactProcessingThreshold(config.contact_processing_threshold);
  btVector3 center;
  btScalar bound_radius;
  shape->getBoundingSphere(center, bound_radius);
  e->radius = bound_radius + center.length();
  if (config.ccd) {
    btVector3 mn, mx;
    shape->getAabb(btTransform::getIdentity(), mn, mx);
    const btVector3 half = (mx - mn) * btScalar(0.5);
    const btScalar inner = std::min({half.x(), half.y(), half.z()});
    body->setCcdMotionThreshold(inner * config.ccd_motion_fraction);
    body->setCcdSweptSphereRadius(inner * config.ccd_swept_radius_fraction);
  }
  if (rb.linear_velocity()) body->setLinearVelocity(ToBt(*rb.linear_velocity()));
  if (rb.angular_velocity()) body->setAngularVelocity(ToBt(*rb.angular_velocity()));
}

// --- Joints

// The constraint between `a` (frame_a in a's frame) and `b` (frame_b in b's frame).
std::unique_ptr<btTypedConstraint> BuildConstraint(const schema::Joint& j, btRigidBody& a,
                                                   btRigidBody& b, const btTransform& frame_a,
                                                   const btTransform& frame_b) {
  switch (j.kind()) {
    case schema::JointKind::Fixed:
      return std::make_unique<btFixedConstraint>(a, b, frame_a, frame_b);
    case schema::JointKind::Hinge:
      return std::make_unique<btHingeConstraint>(a, b, frame_a, frame_b);
    case schema::JointKind::Spring: {
      auto spring = std::make_unique<btGeneric6DofSpring2Constraint>(a, b, frame_a, frame_b);
      spring->setLinearLowerLimit(btVector3(1, 1, 1));  // lower > upper: free
      spring->setLinearUpperLimit(btVector3(-1, -1, -1));
      spring->setAngularLowerLimit(btVector3(1, 1, 1));
      spring->setAngularUpperLimit(btVector3(-1, -1, -1));
      for (int i = 0; i < 3; ++i) {
        spring->enableSpring(i, true);
        spring->setStiffness(i, j.stiffness());
        spring->setDamping(i, j.damping());
      }
      spring->setEquilibriumPoint();
      return spring;
    }
    default:
      return nullptr;
  }
}

// --- Soft body

// Particle positions, masses (default: 1/n each), their bounds and the mean non-zero mass.
struct SoftParticles {
  std::vector<btVector3> x;
  std::vector<btScalar> m;
  btVector3 min, max;
  btScalar mean_mass = 1;
};

SoftParticles ReadParticles(const schema::SoftBody& sb) {
  const auto& p = *sb.particles();
  const int n = static_cast<int>(p.size() / 3);
  SoftParticles out;
  out.x.resize(n);
  out.m.assign(n, btScalar(1.0) / btScalar(n));
  const auto* masses = sb.masses();
  btScalar mass_sum = 0;
  int mass_count = 0;
  btVector3 mn(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), mx = -mn;
  for (int i = 0; i < n; ++i) {
    out.x[i] = btVector3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    mn.setMin(out.x[i]);
    mx.setMax(out.x[i]);
    if (masses != nullptr && masses->size() != 0) out.m[i] = masses->Get(i);
    if (out.m[i] > 0) mass_sum += out.m[i], ++mass_count;
  }
  out.min = mn;
  out.max = mx;
  out.mean_mass = mass_count > 0 ? mass_sum / mass_count : btScalar(1);
  return out;
}

// Links with kLST derived from the spring constant (see physics_world.h), solver settings.
void ConfigureSoftBody(btSoftBody* s, const schema::SoftBody& sb, btScalar mean_mass,
                       const PhysicsConfig& config) {
  btSoftBody::Material* mat = s->m_materials[0];
  // Bullet's position-based links act once per internal step (fixed_dt / substeps).
  const btScalar dt = config.fixed_dt / static_cast<btScalar>(std::max(1, config.substeps));
  btScalar klst = sb.stiffness() * dt * dt * btScalar(2) / mean_mass;
  klst = std::clamp(klst, btScalar(1e-4), btScalar(config.soft_max_link_stiffness));
  mat->m_kLST = klst;
  mat->m_kAST = 0;
  if (const auto* springs = sb.springs()) {
    for (size_t i = 0; i < springs->size(); i += 2) {
      s->appendLink(static_cast<int>(springs->Get(i)), static_cast<int>(springs->Get(i + 1)), mat,
                    false);
    }
  }
  s->m_cfg.kDP = sb.damping();
  s->m_cfg.piterations = config.soft_iterations;
  s->m_cfg.kDF = 0.5;
  // Contact hardness: the fraction of a node's penetration removed per solver iteration.
  // Bullet's default for static/kinematic partners (kKHR 0.1) lets a ~500-node lattice sink
  // ~11 cm into the ground; 1 removes it fully (rigid partners already use kCHR = 1).
  s->m_cfg.kKHR = 1;
  s->m_cfg.kCHR = 1;
  s->getCollisionShape()->setMargin(config.soft_margin);
  if (!config.sleeping) s->setActivationState(DISABLE_DEACTIVATION);
}

}  // namespace

// Step 1: the entity record, linked under its parent (transform-only children keep their pose
// relative to it).
std::unique_ptr<PhysicsWorld::Entity> PhysicsWorld::NewEntity(const schema::Container& c) {
  auto e = std::make_unique<Entity>();
  e->id = c.entity_id();
  e->parent_id = c.parent_id();
  e->flags = c.flags();
  const btTransform xf = internal::TransformOf(c);
  e->xf = xf;
  e->last_good = xf;
  if (e->parent_id != 0) {
    e->parent = Find(e->parent_id);
    e->parent->children.push_back(e.get());
    e->local = e->parent->CurrentTransform().inverse() * xf;
  }
  return e;
}

// Soft-body entities: the btSoftBody, added to the world; the guard's reference state.
void PhysicsWorld::AddSoftBody(Entity* e, const schema::Container& c) {
  const schema::SoftBody& sb = *c.soft_body();
  e->kind = Kind::kSoft;
  SoftParticles particles = ReadParticles(sb);
  const int n = static_cast<int>(particles.x.size());
  e->soft = std::make_unique<btSoftBody>(soft_info_, n, particles.x.data(), particles.m.data());
  btSoftBody* s = e->soft.get();
  ConfigureSoftBody(s, sb, particles.mean_mass, config_);
  s->setUserPointer(e);
  s->setUserIndex(kRoleBody);
  static_cast<btSoftRigidDynamicsWorld*>(world_.get())->addSoftBody(s);
  e->soft_diag0 = std::max((particles.max - particles.min).length(), btScalar(0.1));
  e->soft_good = std::move(particles.x);
  soft_entities_.push_back(e);
}

// Rigid entities (and transform-only ones): kind, shapes, rigid body, trigger object.
void PhysicsWorld::AddRigidParts(Entity* e, const schema::Container& c) {
  e->kind = KindOf(c);
  const BodyShapes shapes = BuildShapes(c, e->kind == Kind::kDynamic, e);
  if (shapes.body != nullptr) AddRigidBody(e, c, shapes);
  if (shapes.trigger != nullptr) AddTrigger(e, shapes.trigger);
}

void PhysicsWorld::AddRigidBody(Entity* e, const schema::Container& c, const BodyShapes& shapes) {
  const schema::RigidBody* rb = c.rigid_body();
  const bool dynamic = e->kind == Kind::kDynamic;
  e->motion = std::make_unique<EntityMotionState>(this, e, e->xf);
  e->body =
      std::make_unique<btRigidBody>(BodyInfo(rb, dynamic, e->motion.get(), shapes.body, config_));
  btRigidBody* body = e->body.get();
  body->setUserPointer(e);
  body->setUserIndex(kRoleBody);
  if (shapes.body_is_trigger) {
    body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_NO_CONTACT_RESPONSE);
  }
  if (e->kind == Kind::kKinematic) {
    body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    body->setActivationState(DISABLE_DEACTIVATION);
  }
  if (dynamic) ConfigureDynamic(body, *rb, shapes.body, config_, e);
  if (shapes.body_collides_nothing) {
    world_->addRigidBody(body, btBroadphaseProxy::DefaultFilter, 0);
  } else {
    world_->addRigidBody(body);
  }
  if (dynamic) {
    // After addRigidBody, which gives the body the world's gravity.
    if (!rb->use_gravity()) {
      body->setFlags(body->getFlags() | BT_DISABLE_WORLD_GRAVITY);
      body->setGravity(btVector3(0, 0, 0));
    }
    e->gravity = body->getGravity();
    e->mass = rb->mass();
    ++dynamic_bodies_;
  }
  ++bodies_;
}

// The separate, non-responding trigger object; it follows moving bodies (ApplyCommands).
void PhysicsWorld::AddTrigger(Entity* e, btCollisionShape* shape) {
  e->trigger = std::make_unique<btCollisionObject>();
  btCollisionObject* t = e->trigger.get();
  t->setCollisionShape(shape);
  t->setWorldTransform(e->xf);
  t->setCollisionFlags(btCollisionObject::CF_NO_CONTACT_RESPONSE);
  t->setUserPointer(e);
  t->setUserIndex(kRoleTrigger);
  t->setActivationState(DISABLE_DEACTIVATION);
  if (e->body) t->setIgnoreCollisionCheck(e->body.get(), true);
  world_->addCollisionObject(t, btBroadphaseProxy::SensorTrigger,
                             btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::SensorTrigger ^
                                 btBroadphaseProxy::StaticFilter);
  if (e->kind == Kind::kDynamic || e->kind == Kind::kKinematic) {
    trigger_followers_.push_back(e);
  }
}

// Joints to the world or to existing bodies, built in the current pose (= rest pose).
void PhysicsWorld::AddJoints(Entity* e, const schema::Container& c) {
  const auto* joints = c.joints();
  if (joints == nullptr) return;
  const btVector3 scale = internal::ScaleOf(c);
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
    const btTransform frame_b = world_b.inverse() * e->xf * frame_a;
    std::unique_ptr<btTypedConstraint> constraint =
        BuildConstraint(*j, body_a, body_b, frame_a, frame_b);
    if (!constraint) continue;
    world_->addConstraint(constraint.get(), true);
    auto rec = std::make_unique<JointRecord>();
    rec->owner = e->id;
    rec->other = other != nullptr ? other->id : 0;
    rec->constraint = std::move(constraint);
    joints_.push_back(std::move(rec));
  }
}

}  // namespace edgephys::physics
