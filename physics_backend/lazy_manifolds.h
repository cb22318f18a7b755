// LazyBoxBoxCreateFunc: box-box contact manifolds only for touching pairs
// (PhysicsConfig::lazy_box_manifolds). Internal to physics/ (PhysicsWorld registers it with its
// dispatcher; callers never see it).
//
// Why: Bullet's btBoxBoxCollisionAlgorithm takes a btPersistentManifold from the dispatcher in
// its constructor, i.e. for EVERY broadphase pair of two boxes, touching or not, and every step
// that manifold is refreshed and then walked by the island manager, by PhyS's contact diff
// (contact_tracker.cc), by RestManager and by the solver setup. In the 2,000-box full stir most
// broadphase pairs do not touch (half the manifolds are empty; it saved ~5 % at best and stays off); a
// profile put the narrowphase's cost in touching a pair's memory, not in the box-box test.
//
// What: a collision algorithm for BOX x BOX pairs with the same geometry as Bullet's (its
// btBoxBoxDetector, its btManifoldResult, its persistent points and refresh), except that
//   - while the pair has no manifold, the detector writes into a small point collector; only
//     when it finds a point within the breaking threshold does the algorithm get a manifold
//     from the dispatcher (btDispatcher::getNewManifold, the same bodies in the same order as
//     Bullet's constructor) and add the points to it through the step's btManifoldResult,
//     then refresh it, as Bullet's algorithm does with an empty manifold: the same points;
//   - while the pair has a manifold, every step is exactly Bullet's (detector into the
//     btManifoldResult, refreshContactPoints);
//   - a manifold that has been empty after `keep_steps` + 1 consecutive processed steps is
//     released (btDispatcher::releaseManifold); the next touch creates a new one.
// getAllContactManifolds reports the manifold only while it exists.
//
// Accuracy: the points of a touching pair are Bullet's for the same poses (tested in
// lazy_manifolds_test.cc); the dispatcher's manifold ORDER differs (manifolds are created at
// the first touch, and releaseManifold moves the array's last manifold into the freed slot),
// so the solver meets contacts in another order and trajectories differ from Bullet's as any
// reordering does. Bullet's island manager wakes a sleeping body that shares a MANIFOLD with an
// active kinematic body; with this algorithm that needs a touching box (within the breaking
// threshold), not only overlapping AABBs.
// Thread-safety: none (the owning PhysicsWorld's thread). Cost: a pair without a manifold costs
// the box-box test only (no manifold memory is touched); getNewManifold / releaseManifold per
// pair that starts touching / has been apart for keep_steps steps (pool or malloc, as Bullet's
// algorithm pays per new broadphase pair).
#pragma once

#include <btBulletCollisionCommon.h>

#include <cstdint>

namespace edgephys::physics {

// Counters shared by the world's lazy algorithms.
struct LazyManifoldStats {
  uint64_t created = 0;   // manifolds taken from the dispatcher at a first touch
  uint64_t released = 0;  // manifolds given back after keep_steps empty steps
};

// Bullet create function for BOX x BOX; register with
// btCollisionDispatcher::registerCollisionCreateFunc(BOX_SHAPE_PROXYTYPE, BOX_SHAPE_PROXYTYPE, f).
// Must outlive the dispatcher's use of it (algorithms it created keep a pointer to `stats`).
class LazyBoxBoxCreateFunc : public btCollisionAlgorithmCreateFunc {
 public:
  // `keep_steps` (>= 0): processed steps an empty manifold is kept before it is released.
  // `relative_threshold`: the dispatcher's CD_USE_RELATIVE_CONTACT_BREAKING_THRESHOLD flag
  // (Bullet's default: set), to find the breaking threshold its manifolds will get.
  LazyBoxBoxCreateFunc(int keep_steps, bool relative_threshold)
      : keep_steps_(keep_steps < 0 ? 0 : keep_steps), relative_threshold_(relative_threshold) {}
  btCollisionAlgorithm* CreateCollisionAlgorithm(btCollisionAlgorithmConstructionInfo& ci,
                                                 const btCollisionObjectWrapper* body0,
                                                 const btCollisionObjectWrapper* body1) override;
  const LazyManifoldStats& stats() const { return stats_; }

 private:
  int keep_steps_;
  bool relative_threshold_;
  LazyManifoldStats stats_;
};

}  // namespace edgephys::physics
