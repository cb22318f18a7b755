// Freezing resting bodies and waking them (see rest_manager.h for the rules).
#include "physics_backend/rest_manager.h"

#include <algorithm>
#include <cmath>

#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {
namespace {

using Entity = PhysicsWorld::Entity;
using internal::Kind;

Entity* Owner(const btCollisionObject* o) {
  if (o == nullptr || o->getUserIndex() != internal::kRoleBody) return nullptr;
  return static_cast<Entity*>(o->getUserPointer());
}

bool IsFrozen(const Entity* e) { return e != nullptr && e->rest.frozen; }

// Collects the frozen bodies whose broadphase AABB a query box overlaps.
struct FrozenCollector : btBroadphaseAabbCallback {
  std::vector<Entity*>* out = nullptr;
  bool process(const btBroadphaseProxy* proxy) override {
    Entity* e = Owner(static_cast<const btCollisionObject*>(proxy->m_clientObject));
    if (IsFrozen(e)) out->push_back(e);
    return true;
  }
};

// Whether a query box overlaps a non-frozen dynamic body moving above the rest thresholds
// (the overlap wake rule, asked per frozen body).
struct MovingNeighbour : btBroadphaseAabbCallback {
  btScalar lin2 = 0, ang2 = 0;
  btVector3 mn{0, 0, 0}, mx{0, 0, 0};  // the query box
  bool found = false;
  bool process(const btBroadphaseProxy* proxy) override {
    // The tree's leaves are fattened: keep only what the pair cache would list (exact AABBs).
    if (!TestAabbAgainstAabb2(mn, mx, proxy->m_aabbMin, proxy->m_aabbMax)) return true;
    const Entity* o = Owner(static_cast<const btCollisionObject*>(proxy->m_clientObject));
    if (o == nullptr || o->rest.frozen || o->kind != Kind::kDynamic) return true;
    const btRigidBody* b = o->body.get();
    if (b->isActive() && b->hasContactResponse() &&
        (b->getLinearVelocity().length2() > lin2 || b->getAngularVelocity().length2() > ang2)) {
      found = true;
      return false;
    }
    return true;
  }
};

// Distance from `p` to the box [mn, mx] (0 inside).
btScalar DistanceToBox(const btVector3& p, const btVector3& mn, const btVector3& mx) {
  btVector3 d(0, 0, 0);
  for (int i = 0; i < 3; ++i) {
    if (p[i] < mn[i]) d[i] = mn[i] - p[i];
    if (p[i] > mx[i]) d[i] = p[i] - mx[i];
  }
  return d.length();
}

}  // namespace

RestManager::RestManager(const PhysicsConfig& config, btDiscreteDynamicsWorld* world)
    : config_(config), world_(world) {
  enabled_ = config.rest_freeze && config.sleeping && config.rest_time > 0;
  lin2_ = config.rest_linear_threshold * config.rest_linear_threshold;
  ang2_ = config.rest_angular_threshold * config.rest_angular_threshold;
  to_wake_.reserve(256);
}

// ---------------------------------------------------------------------------------------------
// Freezing and restoring

void RestManager::Fatten(btRigidBody* body) {
  btVector3 mn, mx;
  body->getCollisionShape()->getAabb(body->getWorldTransform(), mn, mx);
  const btScalar grow = gContactBreakingThreshold + config_.rest_wake_margin;
  const btVector3 g(grow, grow, grow);
  world_->getBroadphase()->setAabb(body->getBroadphaseHandle(), mn - g, mx + g,
                                   world_->getDispatcher());
}

void RestManager::Freeze(Entity* e) {
  btRigidBody* body = e->body.get();
  const btVector3 zero(0, 0, 0);
  e->rest.inv_inertia = body->getInvInertiaDiagLocal();
  body->setLinearVelocity(zero);
  body->setAngularVelocity(zero);
  body->setInterpolationLinearVelocity(zero);
  body->setInterpolationAngularVelocity(zero);
  body->clearForces();
  body->setMassProps(0, zero);  // inverse mass and inertia 0, CF_STATIC_OBJECT
  body->updateInertiaTensor();
  body->forceActivationState(ISLAND_SLEEPING);
  Fatten(body);
  e->rest.frozen = true;
  e->rest.frozen_index = frozen_.size();
  frozen_.push_back(e);
}

void RestManager::Forget(Entity* e) {
  if (!e->rest.frozen) return;
  const size_t i = e->rest.frozen_index;
  frozen_[i] = frozen_.back();
  frozen_[i]->rest.frozen_index = i;
  frozen_.pop_back();
  e->rest.frozen = false;
}

void RestManager::Unfreeze(Entity* e) {
  e->rest.rest_seconds = 0;
  if (!e->rest.frozen) return;
  Forget(e);
  btRigidBody* body = e->body.get();
  // The mass the body was built with, so 1/mass and gravity come out bit-exact; the inverse
  // inertia is put back as it was.
  body->setMassProps(e->mass, btVector3(1, 1, 1));  // clears CF_STATIC_OBJECT
  body->setInvInertiaDiagLocal(e->rest.inv_inertia);
  body->updateInertiaTensor();
  body->forceActivationState(ACTIVE_TAG);
  body->setDeactivationTime(0);
  world_->updateSingleAabb(body);  // the tight AABB again
  ++wakes_;
}

void RestManager::Refatten() {
  for (Entity* e : frozen_) Fatten(e->body.get());
}

// ---------------------------------------------------------------------------------------------
// Wake rules

void RestManager::WakeCollected() {
  for (Entity* e : to_wake_) Unfreeze(e);
  to_wake_.clear();
}

void RestManager::WakeAround(const btVector3& mn, const btVector3& mx) {
  if (frozen_.empty()) return;
  FrozenCollector collect;
  collect.out = &to_wake_;
  world_->getBroadphase()->aabbTest(mn, mx, collect);
  WakeCollected();
}

void RestManager::WakeAroundEntity(const Entity* e) {
  if (frozen_.empty()) return;
  btVector3 mn, mx;
  if (e->body) {
    e->body->getCollisionShape()->getAabb(e->body->getWorldTransform(), mn, mx);
  } else if (e->soft) {
    e->soft->getAabb(mn, mx);
  } else {
    return;
  }
  const btScalar grow = gContactBreakingThreshold + config_.rest_wake_margin;
  const btVector3 g(grow, grow, grow);
  WakeAround(mn - g, mx + g);
}

// Whether kinematic `k`, moving from k->move_from to its target this step, comes close enough
// to frozen `f` to touch it: f's bounding sphere against k's local AABB at both poses, grown by
// the wake margin and the farthest any point of k moves this step.
bool RestManager::KinematicReaches(const Entity* k, const Entity* f) const {
  const btCollisionShape* shape = k->body->getCollisionShape();
  btVector3 lmn, lmx;
  shape->getAabb(btTransform::getIdentity(), lmn, lmx);
  btVector3 center;
  btScalar k_radius;
  shape->getBoundingSphere(center, k_radius);
  k_radius += center.length();
  const btTransform& from = k->move_from;
  const btTransform& to = k->target;
  const btScalar angle = from.getRotation().angleShortestPath(to.getRotation());
  const btScalar sweep = (to.getOrigin() - from.getOrigin()).length() + angle * k_radius;
  const btScalar reach = f->radius + config_.rest_wake_margin + gContactBreakingThreshold + sweep;
  const btVector3& p = f->body->getWorldTransform().getOrigin();
  return DistanceToBox(from.invXform(p), lmn, lmx) < reach ||
         DistanceToBox(to.invXform(p), lmn, lmx) < reach;
}

void RestManager::BeforeStep(const std::vector<Entity*>& moving, bool has_soft_bodies) {
  if (!enabled_) return;
  // Kinematic bodies sweep their whole path this step (the pair cache is last step's).
  if (!frozen_.empty()) {
    std::vector<Entity*>& hits = to_wake_;
    FrozenCollector collect;
    collect.out = &hits;
    for (const Entity* k : moving) {
      if (!k->body || !k->body->hasContactResponse()) continue;
      const btCollisionShape* shape = k->body->getCollisionShape();
      btVector3 a0, a1, b0, b1;
      shape->getAabb(k->move_from, a0, a1);
      shape->getAabb(k->target, b0, b1);
      a0.setMin(b0);
      a1.setMax(b1);
      const size_t first = hits.size();
      world_->getBroadphase()->aabbTest(a0, a1, collect);
      // Keep only the hits the kinematic body's shape actually comes near.
      size_t kept = first;
      for (size_t i = first; i < hits.size(); ++i) {
        if (KinematicReaches(k, hits[i])) hits[kept++] = hits[i];
      }
      hits.resize(kept);
    }
  }
  if (frozen_.empty() && !has_soft_bodies && to_wake_.empty()) return;
  btOverlappingPairCache* cache = world_->getBroadphase()->getOverlappingPairCache();
  // Few frozen bodies among many pairs (a scene where almost nothing rests): ask the
  // broadphase around each frozen body instead of walking every pair.
  if (!has_soft_bodies &&
      frozen_.size() * kPairsPerFrozenQuery < static_cast<size_t>(cache->getNumOverlappingPairs())) {
    MovingNeighbour probe;
    probe.lin2 = lin2_;
    probe.ang2 = ang2_;
    for (Entity* f : frozen_) {
      const btBroadphaseProxy* h = f->body->getBroadphaseHandle();
      probe.found = false;
      probe.mn = h->m_aabbMin;
      probe.mx = h->m_aabbMax;
      world_->getBroadphase()->aabbTest(h->m_aabbMin, h->m_aabbMax, probe);
      if (probe.found) to_wake_.push_back(f);
    }
    WakeCollected();
    return;
  }
  // Overlapping pairs: a frozen body next to a moving non-frozen one (or a soft body) wakes;
  // a dynamic body next to a soft body restarts its rest time (never frozen while touching).
  btBroadphasePairArray& pairs = cache->getOverlappingPairArray();
  for (int i = 0; i < pairs.size(); ++i) {
    const auto* o0 = static_cast<const btCollisionObject*>(pairs[i].m_pProxy0->m_clientObject);
    const auto* o1 = static_cast<const btCollisionObject*>(pairs[i].m_pProxy1->m_clientObject);
    Entity* e0 = Owner(o0);
    Entity* e1 = Owner(o1);
    if (e0 == nullptr || e1 == nullptr) continue;
    const bool f0 = e0->rest.frozen, f1 = e1->rest.frozen;
    if (f0 == f1) {
      if (f0 || !has_soft_bodies) continue;
      if (e0->kind == Kind::kSoft && e1->kind == Kind::kDynamic) e1->rest.rest_seconds = 0;
      if (e1->kind == Kind::kSoft && e0->kind == Kind::kDynamic) e0->rest.rest_seconds = 0;
      continue;
    }
    Entity* f = f0 ? e0 : e1;
    const Entity* o = f0 ? e1 : e0;
    if (o->kind == Kind::kSoft) {
      to_wake_.push_back(f);
    } else if (o->kind == Kind::kDynamic && o->body->isActive() &&
               o->body->hasContactResponse() &&
               (o->body->getLinearVelocity().length2() > lin2_ ||
                o->body->getAngularVelocity().length2() > ang2_)) {
      to_wake_.push_back(f);
    }
  }
  WakeCollected();
}

void RestManager::AfterStep(const std::vector<Entity*>& stepped, float dt) {
  if (!enabled_) return;
  // Contact impulses: a frozen body pushed harder than rest_wake_delta_v * its mass wakes.
  if (!frozen_.empty()) {
    btDispatcher* d = world_->getDispatcher();
    const int manifolds = d->getNumManifolds();
    for (int i = 0; i < manifolds; ++i) {
      const btPersistentManifold* m = d->getManifoldByIndexInternal(i);
      Entity* e0 = Owner(m->getBody0());
      Entity* e1 = Owner(m->getBody1());
      if (IsFrozen(e0) == IsFrozen(e1)) continue;
      Entity* f = IsFrozen(e0) ? e0 : e1;
      const btCollisionObject* other = IsFrozen(e0) ? m->getBody1() : m->getBody0();
      // Only manifolds Bullet solved this step (an active, non-static partner).
      if (!other->isActive() || other->isStaticOrKinematicObject()) continue;
      btScalar impulse = 0;
      for (int k = 0; k < m->getNumContacts(); ++k) impulse += m->getContactPoint(k).getAppliedImpulse();
      if (impulse > config_.rest_wake_delta_v * f->mass) to_wake_.push_back(f);
    }
    WakeCollected();
  }
  // Rest time and freezing, for the bodies Bullet stepped.
  for (Entity* e : stepped) {
    if (e->kind != Kind::kDynamic || e->rest.frozen) continue;
    btRigidBody* body = e->body.get();
    if (e->grabbed || body->getNumConstraintRefs() > 0 || !body->hasContactResponse() ||
        !body->isActive() || body->getActivationState() == DISABLE_DEACTIVATION) {
      e->rest.rest_seconds = 0;
      continue;
    }
    if (body->getLinearVelocity().length2() > lin2_ ||
        body->getAngularVelocity().length2() > ang2_) {
      e->rest.rest_seconds = 0;
      continue;
    }
    e->rest.rest_seconds += dt;
    if (e->rest.rest_seconds >= config_.rest_time) Freeze(e);
  }
}

}  // namespace edgephys::physics
