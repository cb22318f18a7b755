// RestManager: "rest resting regions" (per-body freezing, PhysicsConfig::rest_freeze). Internal
// to physics/ (PhysicsWorld owns one; callers of PhysicsWorld never see it).
//
// Why: Bullet builds islands from broadphase pairs, so a pile that is stirred anywhere is one
// island and never sleeps, although most of its boxes rest between passes. Freezing lets the
// resting part drop out of the solver and the narrowphase body by body.
//
// What: a dynamic rigid body whose linear and angular speed stay below rest_linear_threshold /
// rest_angular_threshold for rest_time seconds is FROZEN: its velocity is zeroed and it is made
// temporarily static to Bullet (inverse mass and inverse inertia 0, CF_STATIC_OBJECT, so it no
// longer merges islands; ISLAND_SLEEPING, so frozen-frozen and frozen-static pairs are skipped
// by the dispatcher and its AABB is no longer updated). Its broadphase AABB is fattened by
// rest_wake_margin so that the pair cache lists every body that comes within that distance.
// It keeps its mass and inverse inertia to restore.
//
// A frozen body is UNFROZEN (restored bit-exactly, velocity zero, active) when something could
// move it:
//   * before a step: a broadphase-overlapping non-frozen dynamic body above the rest thresholds,
//     an overlapping soft body, or a kinematic body whose swept pose this step comes within
//     rest_wake_margin + its displacement of the frozen body's bounding sphere;
//   * after a step: a contact with a non-frozen body whose impulse on it this step exceeds
//     rest_wake_delta_v times its mass (a body resting on it pushes g * dt);
//   * API calls (PhysicsWorld calls Unfreeze / WakeAround): SetTransform / SetVelocity / Grab /
//     a joint to it unfreeze it; adding, removing or teleporting any entity unfreezes every
//     frozen body whose fattened AABB overlaps the entity's AABB (old and new), so a stack whose
//     support is removed falls.
// Waking cascades: a woken body that then moves wakes its frozen neighbours before the next
// step. Never frozen: grabbed bodies, bodies with joints (constraint refs), bodies without
// contact response, bodies overlapping a soft body, and anything when PhysicsConfig::sleeping
// is false.
//
// Thread-safety: none (the owning PhysicsWorld's thread). Ownership: holds non-owning pointers
// to the world's Bullet world and entities; PhysicsWorld calls Forget() before deleting one.
// Cost: BeforeStep O(broadphase pairs) when anything is frozen or a soft body exists, or
// O(frozen bodies * log n) when frozen bodies are few against the pairs (a scene where almost
// nothing rests: freezing then costs ~nothing beyond AfterStep's pass over stepped bodies), plus
// O(collision objects) per moving kinematic body (aabbTest); AfterStep O(contact manifolds +
// bodies stepped). No allocation in steady state.
#pragma once

#include <btBulletDynamicsCommon.h>

#include <cstddef>
#include <vector>

#include "physics_backend/physics_world.h"

namespace edgephys::physics {

// Per-entity freezing state (PhysicsWorld::Entity::rest).
struct RestState {
  bool frozen = false;
  float rest_seconds = 0;          // time spent below the rest thresholds
  size_t frozen_index = 0;         // position in RestManager's frozen list while frozen
  btVector3 inv_inertia{0, 0, 0};  // the body's inverse local inertia, restored on unfreezing
};

class RestManager {
 public:
  RestManager(const PhysicsConfig& config, btDiscreteDynamicsWorld* world);

  bool enabled() const { return enabled_; }
  size_t frozen() const { return frozen_.size(); }
  // Bodies unfrozen since construction (all causes); for tests and reports.
  uint64_t wakes() const { return wakes_; }

  // Before Bullet steps: the overlap and kinematic-sweep wake rules, and soft-body pinning.
  // `moving`: kinematic entities with a target this step (their motion state holds the target,
  // Entity::move_from the pose before).
  void BeforeStep(const std::vector<PhysicsWorld::Entity*>& moving, bool has_soft_bodies);
  // After Bullet stepped: the contact-impulse wake rule, then bodies Bullet stepped (`stepped`)
  // accumulate rest time and freeze. `dt`: the step's length (s).
  void AfterStep(const std::vector<PhysicsWorld::Entity*>& stepped, float dt);

  // Restores `e` if frozen and restarts its rest time (any API call that touches it).
  void Unfreeze(PhysicsWorld::Entity* e);
  // Unfreezes every frozen body whose (fattened) AABB overlaps [mn, mx]. O(collision objects)
  // with the axis sweep, O(log n + hits) with the dbvt; nothing when nothing is frozen.
  void WakeAround(const btVector3& mn, const btVector3& mx);
  // WakeAround the current AABB of `e`'s body or soft body, grown by the wake margin.
  void WakeAroundEntity(const PhysicsWorld::Entity* e);
  // `e` is being removed: drops it from the frozen list (no Bullet calls).
  void Forget(PhysicsWorld::Entity* e);
  // The broadphase was rebuilt (proxies have tight AABBs): fattens the frozen bodies again.
  void Refatten();

 private:
  void Freeze(PhysicsWorld::Entity* e);
  void Fatten(btRigidBody* body);
  bool KinematicReaches(const PhysicsWorld::Entity* k, const PhysicsWorld::Entity* f) const;
  void WakeCollected();
  // BeforeStep asks the broadphase per frozen body (O(log n) each with the axis sweep's or the
  // dbvt's tree) instead of walking every pair when pairs outnumber frozen bodies this much.
  static constexpr size_t kPairsPerFrozenQuery = 16;

  const PhysicsConfig& config_;
  btDiscreteDynamicsWorld* world_;
  bool enabled_ = false;
  btScalar lin2_ = 0;  // squared thresholds
  btScalar ang2_ = 0;
  std::vector<PhysicsWorld::Entity*> frozen_;
  std::vector<PhysicsWorld::Entity*> to_wake_;  // scratch
  uint64_t wakes_ = 0;
};

}  // namespace edgephys::physics
