// PhysicsWorld's front: the Bullet world's lifetime, AddEntity/RemoveEntity, commands, the
// fixed step and its output. Validation, body building, the stability guard and contact
// tracking live in the files listed in physics_world_internal.h.
#include "physics_backend/physics_world.h"

#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <algorithm>
#include <cmath>

#include "physics_backend/bullet_world.h"
#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {

using internal::Finite;
using internal::InsideWorld;
using internal::Kind;
using internal::SameState;
using internal::ToBt;
using internal::ToState;
using internal::ToVec;

void EntityMotionState::setWorldTransform(const btTransform& in) {
  xf_ = in;
  if (!entity_->in_stepped) {
    entity_->in_stepped = true;
    world_->stepped_.push_back(entity_);
  }
}

PhysicsWorld::PhysicsWorld(const PhysicsConfig& config) : config_(config) {
  btDefaultCollisionConstructionInfo pools;
  pools.m_defaultMaxPersistentManifoldPoolSize = std::max(64, config_.contact_pool_size);
  pools.m_defaultMaxCollisionAlgorithmPoolSize = std::max(64, config_.contact_pool_size);
  if (config_.soft_body_world) {
    collision_config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>(pools);
  } else {
    collision_config_ = std::make_unique<btDefaultCollisionConfiguration>(pools);
  }
  dispatcher_ = std::make_unique<btCollisionDispatcher>(collision_config_.get());
  broadphase_ = NewBroadphase(kInitialSweepHandles);
  solver_ = internal::NewSolver(config_);
  world_ = internal::NewBulletWorld(config_, dispatcher_.get(), broadphase_.get(), solver_.get(),
                                    collision_config_.get(), &soft_info_);
  internal::ApplyWorldSettings(config_, world_.get());
  if (soft_info_ != nullptr) {
    soft_info_->m_gravity = ToBt(config_.gravity);
    soft_info_->air_density = 0;
    soft_info_->water_density = 0;
  }
  // gDeactivationTime is Bullet's process-wide constant; other values are emulated per body
  // (RunGuard scales the time a body has been below the thresholds).
  deactivation_scale_ = config_.deactivation_time > 0
                            ? btScalar(2.0) / config_.deactivation_time - btScalar(1)
                            : btScalar(0);
  fixed_body_ = std::make_unique<btRigidBody>(0, nullptr, nullptr);
  fixed_body_->setMassProps(0, btVector3(0, 0, 0));
  rest_ = std::make_unique<RestManager>(config_, world_.get());
  const size_t reserve = 1024;
  stepped_.reserve(reserve);
  dirty_.reserve(reserve);
  pairs_.reserve(reserve);
  new_pairs_.reserve(reserve);
  events_.reserve(256);
  step_events_.reserve(256);
}

std::unique_ptr<btBroadphaseInterface> PhysicsWorld::NewBroadphase(int handles) {
  sweep_handles_ = 0;
  if (config_.broadphase != PhysicsConfig::Broadphase::kAxisSweep) {
    return std::make_unique<btDbvtBroadphase>();
  }
  sweep_handles_ = handles;
  const btScalar b = config_.world_half_extent;
  return std::make_unique<bt32BitAxisSweep3>(btVector3(-b, -b, -b), btVector3(b, b, b),
                                             static_cast<unsigned int>(handles));
}

void PhysicsWorld::ReserveBroadphase(int more) {
  if (sweep_handles_ == 0) return;  // btDbvtBroadphase grows by itself
  const int needed = world_->getNumCollisionObjects() + more;
  if (needed <= sweep_handles_ - 2) return;  // the sweep keeps two sentinel handles
  int handles = sweep_handles_;
  while (handles - 2 < needed) handles *= 2;
  // Re-home every collision object: its pairs, algorithms and manifolds go with the old
  // broadphase (contacts are found again by the next step).
  btCollisionObjectArray& objects = world_->getCollisionObjectArray();
  struct Filter {
    int group;
    int mask;
  };
  std::vector<Filter> filters(static_cast<size_t>(objects.size()));
  for (int i = 0; i < objects.size(); ++i) {
    btBroadphaseProxy* proxy = objects[i]->getBroadphaseHandle();
    filters[i] = Filter{proxy->m_collisionFilterGroup, proxy->m_collisionFilterMask};
    broadphase_->getOverlappingPairCache()->cleanProxyFromPairs(proxy, dispatcher_.get());
    broadphase_->destroyProxy(proxy, dispatcher_.get());
    objects[i]->setBroadphaseHandle(nullptr);
  }
  std::unique_ptr<btBroadphaseInterface> grown = NewBroadphase(handles);
  world_->setBroadphase(grown.get());
  for (int i = 0; i < objects.size(); ++i) {
    btCollisionObject* o = objects[i];
    btVector3 mn, mx;
    o->getCollisionShape()->getAabb(o->getWorldTransform(), mn, mx);
    o->setBroadphaseHandle(grown->createProxy(mn, mx, o->getCollisionShape()->getShapeType(), o,
                                              filters[i].group, filters[i].mask,
                                              dispatcher_.get()));
  }
  broadphase_ = std::move(grown);
  for (int i = 0; i < objects.size(); ++i) world_->updateSingleAabb(objects[i]);
  rest_->Refatten();
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
// Entities

InvalidReason PhysicsWorld::Validate(const schema::Container& c) const {
  return internal::ValidateContainer(c, config_, entities_);
}

Status PhysicsWorld::AddEntity(const schema::Container& c, InvalidReason* reason) {
  const InvalidReason why = Validate(c);
  if (reason != nullptr) *reason = why;
  if (why != InvalidReason::kNone) {
    ++stats_.rejected_containers;
    return internal::RejectionStatus(why);
  }
  ReserveBroadphase(2);  // a body and a trigger object at most
  std::unique_ptr<Entity> owned = NewEntity(c);
  Entity* e = owned.get();
  if (c.soft_body() != nullptr) {
    AddSoftBody(e, c);
  } else {
    AddRigidParts(e, c);
    AddJoints(e, c);
    for (const auto& j : joints_) {
      if (j->owner == e->id && j->other != 0) rest_->Unfreeze(Find(j->other));
    }
  }
  rest_->WakeAroundEntity(e);  // something now occupies that space
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
  rest_->Forget(e);
  rest_->WakeAroundEntity(e);  // whatever rested on it must fall
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
  if (Status st = internal::CheckPose(pos, rot, config_); !st.ok()) return st;
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
  if (Status st = internal::CheckPose(pos, rot, config_); !st.ok()) return st;
  if (e->kind == Kind::kSoft) return Status(StatusCode::kInvalidArgument, "soft body");
  const btTransform t(ToBt(rot), ToBt(pos));
  if (e->body) {
    btRigidBody* body = e->body.get();
    rest_->Unfreeze(e);
    rest_->WakeAroundEntity(e);  // what rested on it or against it at the old pose
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
  if (e->body) rest_->WakeAroundEntity(e);  // and at the new one
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
  rest_->Unfreeze(e);
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
  rest_->Unfreeze(e);
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

Status PhysicsWorld::SetSoftBodyNodes(uint32_t id, uint32_t first, std::span<const Vec3f> nodes) {
  Entity* e = Find(id);
  if (e == nullptr || !e->soft) return Status(StatusCode::kNotFound, "no such soft body");
  btSoftBody::tNodeArray& body = e->soft->m_nodes;
  const size_t total = static_cast<size_t>(body.size());
  if (first > total || nodes.size() > total - first) {
    return Status::InvalidArgument("nodes beyond the soft body's node count");
  }
  for (const Vec3f& n : nodes) {
    if (!Finite(n)) return Status(StatusCode::kInvalidArgument, "non-finite node position");
    if (!InsideWorld(n, config_)) {
      return Status(StatusCode::kInvalidArgument, "node position outside the world bounds");
    }
  }
  const btVector3 zero(0, 0, 0);
  for (size_t i = 0; i < nodes.size(); ++i) {
    btSoftBody::Node& node = body[static_cast<int>(first + i)];
    node.m_x = node.m_q = ToBt(nodes[i]);
    node.m_v = zero;
    node.m_f = zero;
    if (first + i < e->soft_good.size()) e->soft_good[first + i] = node.m_x;
  }
  e->soft->updateBounds();
  e->soft->updateNormals();
  e->soft->activate(true);
  MarkDirty(e);
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
  rest_->BeforeStep(moving_, !soft_entities_.empty());
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
  rest_->AfterStep(stepped_, config_.fixed_dt);
  stepped_.clear();
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
  c.frozen_bodies = rest_->frozen();
  c.rest_wakes = rest_->wakes();
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
