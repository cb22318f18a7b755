// The stability guard, run after every Step(): bodies Bullet moved this step and active soft
// bodies are checked for non-finite state, runaway speed, leaving the world bounds and (soft
// bodies) exploding; offenders are restored to their last good state and reported as
// kGuardReset events. O(bodies moved this step + nodes of active soft bodies), no allocation.
#include <algorithm>
#include <cmath>

#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {
namespace {

using internal::Finite;

// What is wrong with a rigid body after a step (kNone: nothing). `radius`: its bounding radius
// around the origin.
GuardCause CheckRigid(const btRigidBody& body, btScalar radius, const PhysicsConfig& config) {
  const btScalar max_v2 = config.max_linear_speed * config.max_linear_speed;
  const btScalar max_w2 = config.max_angular_speed * config.max_angular_speed;
  const btTransform& t = body.getWorldTransform();
  const btVector3& v = body.getLinearVelocity();
  const btVector3& w = body.getAngularVelocity();
  if (!Finite(t) || !Finite(v) || !Finite(w)) return GuardCause::kNonFinite;
  if (v.length2() > max_v2 || w.length2() > max_w2) return GuardCause::kRunawaySpeed;
  const btVector3& o = t.getOrigin();
  const btScalar lim = config.world_half_extent - radius;
  if (std::abs(o.x()) > lim || std::abs(o.y()) > lim || std::abs(o.z()) > lim) {
    return GuardCause::kOutOfBounds;
  }
  return GuardCause::kNone;
}

// What is wrong with a soft body after a step. `diag0`: its AABB diagonal when added.
GuardCause CheckSoft(const btSoftBody& s, btScalar diag0, const PhysicsConfig& config) {
  const btSoftBody::tNodeArray& nodes = s.m_nodes;
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
  const btScalar bound = config.world_half_extent;
  if (!finite) return GuardCause::kNonFinite;
  if (max_v2 > config.soft_max_node_speed * config.soft_max_node_speed ||
      (mx - mn).length() > diag0 * config.soft_max_extent_ratio) {
    return GuardCause::kSoftBodyExploded;
  }
  if (mn.x() < -bound || mn.y() < -bound || mn.z() < -bound || mx.x() > bound || mx.y() > bound ||
      mx.z() > bound) {
    return GuardCause::kOutOfBounds;
  }
  return GuardCause::kNone;
}

// Puts every node back at `good`, at rest.
void RestoreSoftNodes(btSoftBody* s, const std::vector<btVector3>& good) {
  btSoftBody::tNodeArray& nodes = s->m_nodes;
  const btVector3 zero(0, 0, 0);
  for (int i = 0; i < nodes.size(); ++i) {
    btSoftBody::Node& node = nodes[i];
    node.m_x = node.m_q = good[i];
    node.m_v = zero;
    node.m_f = zero;
  }
  s->updateBounds();
}

// Clamps every material's kLST to 1 (unconditionally stable); true if any was above.
bool SoftenLinks(btSoftBody* s) {
  bool softened = false;
  for (int i = 0; i < s->m_materials.size(); ++i) {
    if (s->m_materials[i]->m_kLST > btScalar(1)) {
      s->m_materials[i]->m_kLST = 1;
      softened = true;
    }
  }
  if (softened) s->m_bUpdateRtCst = true;
  return softened;
}

}  // namespace

void PhysicsWorld::RunGuard() {
  for (Entity* e : stepped_) {
    e->in_stepped = false;
    const GuardCause cause = CheckRigid(*e->body, e->radius, config_);
    if (cause == GuardCause::kNone) {
      e->last_good = e->body->getWorldTransform();
      // Bullet counted this step below the sleep thresholds (time > 0): scale it so that the
      // island sleeps after config_.deactivation_time instead of Bullet's global 2 s.
      const btScalar below = e->body->getDeactivationTime();
      if (deactivation_scale_ != 0 && below > 0) {
        e->body->setDeactivationTime(
            std::max(below + deactivation_scale_ * config_.fixed_dt, btScalar(1e-6)));
      }
    } else {
      ResetRigid(e, cause);
    }
    MarkDirty(e);
  }
  last_active_ = stepped_.size();  // Step() clears stepped_ after the rest manager read it
  for (Entity* e : soft_entities_) {
    if (!e->soft->isActive()) continue;
    RunSoftGuard(e);
    MarkDirty(e);
  }
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
    body->forceActivationState(e->grabbed || !config_.sleeping ? DISABLE_DEACTIVATION : ACTIVE_TAG);
    body->setDeactivationTime(0);
  }
  world_->updateSingleAabb(body);
  ++stats_.guard_resets;
  PushEvent(PhysicsEvent{PhysicsEventType::kGuardReset, cause, e->id, 0, stats_.steps});
}

void PhysicsWorld::RunSoftGuard(Entity* e) {
  btSoftBody* s = e->soft.get();
  const GuardCause cause = CheckSoft(*s, e->soft_diag0, config_);
  if (cause == GuardCause::kNone) {
    const btSoftBody::tNodeArray& nodes = s->m_nodes;
    for (int i = 0; i < nodes.size(); ++i) e->soft_good[i] = nodes[i].m_x;
    e->soft_consecutive_resets = 0;
    return;
  }
  RestoreSoftNodes(s, e->soft_good);
  ++e->soft_consecutive_resets;
  if (e->soft_consecutive_resets >= config_.soft_soften_after_resets && SoftenLinks(s)) {
    ++stats_.soft_softened;
  }
  ++stats_.guard_resets;
  PushEvent(PhysicsEvent{PhysicsEventType::kGuardReset, cause, e->id, 0, stats_.steps});
}

}  // namespace edgephys::physics
