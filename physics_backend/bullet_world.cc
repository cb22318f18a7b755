#include "physics_backend/bullet_world.h"

#include "physics_backend/contact_solver.h"

#include <BulletCollision/CollisionDispatch/btSimulationIslandManager.h>
#include <BulletDynamics/ConstraintSolver/btNNCGConstraintSolver.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <utility>
#include <vector>

namespace edgephys::physics::internal {
namespace {

bool Inside(const btVector3& mn, const btVector3& mx, const btVector3& outer_mn,
            const btVector3& outer_mx) {
  return mn.x() >= outer_mn.x() && mn.y() >= outer_mn.y() && mn.z() >= outer_mn.z() &&
         mx.x() <= outer_mx.x() && mx.y() <= outer_mx.y() && mx.z() <= outer_mx.z();
}

// Bullet's world with PhyS's CCD scope and AABB rules (see the header and PhysicsConfig).
template <class Base>
class TunedWorld final : public Base {
 public:
  template <class... Args>
  explicit TunedWorld(const PhysicsConfig& config, Args&&... args)
      : Base(std::forward<Args>(args)...),
        static_ccd_(config.ccd_static_only),
        margin_(config.aabb_margin),
        hysteresis_(config.aabb_hysteresis) {}

 protected:
  // createPredictiveContacts and integrateTransforms are the two passes that sweep; both copy
  // the filter mask of the body's broadphase proxy into their result callback.
  void createPredictiveContacts(btScalar dt) override {
    Narrow();
    Base::createPredictiveContacts(dt);
    Restore();
  }
  void integrateTransforms(btScalar dt) override {
    Narrow();
    Base::integrateTransforms(dt);
    Restore();
  }
  // Dynamic rigid bodies: the AABB over the current and the predicted pose (as Bullet), grown by
  // margin_ instead of gContactBreakingThreshold, and with hysteresis_ > 0 handed to the
  // broadphase grown by hysteresis_ only when it left the one the broadphase holds. Everything
  // else: Bullet's own update.
  void updateAabbs() override {
    btBroadphaseInterface* bp = this->getBroadphase();
    const btVector3 margin(margin_, margin_, margin_);
    const btVector3 fat(hysteresis_, hysteresis_, hysteresis_);
    for (int i = 0; i < this->m_collisionObjects.size(); ++i) {
      btCollisionObject* o = this->m_collisionObjects[i];
      if (!this->m_forceUpdateAllAabbs && !o->isActive()) continue;
      btBroadphaseProxy* p = o->getBroadphaseHandle();
      if (btRigidBody::upcast(o) == nullptr || o->isStaticOrKinematicObject() || p == nullptr) {
        this->updateSingleAabb(o);
        continue;
      }
      btVector3 mn, mx, mn2, mx2;
      const btCollisionShape* shape = o->getCollisionShape();
      shape->getAabb(o->getWorldTransform(), mn, mx);
      shape->getAabb(o->getInterpolationWorldTransform(), mn2, mx2);
      mn.setMin(mn2);
      mx.setMax(mx2);
      mn -= margin;
      mx += margin;
      if (!((mx - mn).length2() < btScalar(1e12))) {  // far out or non-finite: Bullet's path
        this->updateSingleAabb(o);
        continue;
      }
      if (hysteresis_ > 0) {
        if (Inside(mn, mx, p->m_aabbMin, p->m_aabbMax)) continue;
        mn -= fat;
        mx += fat;
      }
      bp->setAabb(p, mn, mx, this->m_dispatcher1);
    }
  }

 private:
  struct Saved {
    btBroadphaseProxy* proxy;
    int mask;
  };
  void Narrow() {
    saved_.clear();
    if (!static_ccd_) return;
    for (int i = 0; i < this->m_nonStaticRigidBodies.size(); ++i) {
      btRigidBody* b = this->m_nonStaticRigidBodies[i];
      btBroadphaseProxy* p = b->getBroadphaseHandle();
      if (p == nullptr || b->isStaticOrKinematicObject() || b->getCcdSquareMotionThreshold() <= 0) {
        continue;
      }
      saved_.push_back(Saved{p, p->m_collisionFilterMask});
      p->m_collisionFilterMask &= btBroadphaseProxy::StaticFilter;
    }
  }
  void Restore() {
    for (const Saved& s : saved_) s.proxy->m_collisionFilterMask = s.mask;
    saved_.clear();
  }
  bool static_ccd_;
  btScalar margin_;
  btScalar hysteresis_;
  std::vector<Saved> saved_;
};

// Whether the config needs TunedWorld (otherwise Bullet's own world, bit for bit).
bool Tuned(const PhysicsConfig& c) {
  return c.ccd_static_only || c.aabb_hysteresis > 0 ||
         c.aabb_margin != kBulletAabbMargin;
}

}  // namespace

std::unique_ptr<btConstraintSolver> NewSolver(const PhysicsConfig& config) {
  // PhyS's solver (contact_solver.h) only where a setting needs it: one solver batch needs its
  // response filter, patch friction its rows. Otherwise Bullet's own solver, bit for bit.
  const bool own = config.patch_friction || !config.split_islands;
  if (config.solver == PhysicsConfig::Solver::kNNCG) {
    if (own) return std::make_unique<ContactSolver<btNNCGConstraintSolver>>(false);
    return std::make_unique<btNNCGConstraintSolver>();
  }
  if (own) {
    return std::make_unique<ContactSolver<btSequentialImpulseConstraintSolver>>(
        config.patch_friction);
  }
  return std::make_unique<btSequentialImpulseConstraintSolver>();
}

std::unique_ptr<btDiscreteDynamicsWorld> NewBulletWorld(const PhysicsConfig& config,
                                                        btCollisionDispatcher* dispatcher,
                                                        btBroadphaseInterface* broadphase,
                                                        btConstraintSolver* solver,
                                                        btCollisionConfiguration* collision_config,
                                                        btSoftBodyWorldInfo** soft_info) {
  *soft_info = nullptr;
  if (config.soft_body_world) {
    std::unique_ptr<btSoftRigidDynamicsWorld> w;
    if (Tuned(config)) {
      w = std::make_unique<TunedWorld<btSoftRigidDynamicsWorld>>(
          config, dispatcher, broadphase, solver, collision_config);
    } else {
      w = std::make_unique<btSoftRigidDynamicsWorld>(dispatcher, broadphase, solver,
                                                     collision_config);
    }
    *soft_info = &w->getWorldInfo();
    return w;
  }
  if (Tuned(config)) {
    return std::make_unique<TunedWorld<btDiscreteDynamicsWorld>>(
        config, dispatcher, broadphase, solver, collision_config);
  }
  return std::make_unique<btDiscreteDynamicsWorld>(dispatcher, broadphase, solver,
                                                   collision_config);
}

void ApplyWorldSettings(const PhysicsConfig& config, btDiscreteDynamicsWorld* world) {
  world->setGravity(btVector3(config.gravity.x, config.gravity.y, config.gravity.z));
  btContactSolverInfo& info = world->getSolverInfo();
  info.m_numIterations = config.solver_iterations;
  info.m_splitImpulse = config.split_impulse;
  info.m_warmstartingFactor = config.warmstarting_factor;
  if (config.warmstarting_factor <= 0) info.m_solverMode &= ~SOLVER_USE_WARMSTARTING;
  if (config.randomize_solver_order) info.m_solverMode |= SOLVER_RANDMIZE_ORDER;
  if (config.two_friction_directions) info.m_solverMode |= SOLVER_USE_2_FRICTION_DIRECTIONS;
  if (config.friction_direction_caching) {
    info.m_solverMode |= SOLVER_ENABLE_FRICTION_DIRECTION_CACHING;
  }
  if (!config.velocity_dependent_friction) {
    info.m_solverMode |= SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION;
  }
  if (config.interleave_friction && !config.patch_friction) {
    info.m_solverMode |= SOLVER_INTERLEAVE_CONTACT_AND_FRICTION_CONSTRAINTS;
  }
  info.m_leastSquaresResidualThreshold = config.solver_residual_threshold;
  world->getSimulationIslandManager()->setSplitIslands(config.split_islands);
  // Static AABBs never change unless PhysicsWorld moves them (it then updates them explicitly).
  world->setForceUpdateAllAabbs(false);
  // CCD creates predictive contacts; without this they silently drop restitution.
  world->setApplySpeculativeContactRestitution(true);
}

}  // namespace edgephys::physics::internal
