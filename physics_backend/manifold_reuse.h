// ManifoldReuse: contact manifold reuse for box-box pairs (PhysicsConfig::manifold_reuse_distance).
// Internal to physics/ (PhysicsWorld registers it with its dispatcher; callers never see it).
//
// Why: in a pile that moves as a flow (the fully stirred MultiObject scene), most touching
// boxes move together; re-running the box-box narrowphase (btBoxBoxDetector: clipping, point
// culling, manifold merge) for a pair whose relative pose barely changed recomputes the same
// contact points. The narrowphase is about a third of a 2,000-box step.
//
// What: a collision algorithm for BOX x BOX pairs that derives from Bullet's
// btBoxBoxCollisionAlgorithm. When it runs the full narrowphase it records the pair's relative
// transform (body 1 in body 0's frame). On later steps, if that relative transform differs from
// the recorded one by at most `distance` - measured as the translation of body 1's origin in
// body 0's frame plus the relative rotation angle times body 1's bounding radius, i.e. a bound on
// how far any point of body 1 moved relative to body 0 - it skips the narrowphase and only
// refreshes the kept manifold: contact normals are turned with body 1's rotation since the last
// step (a face normal is fixed to its box), then Bullet's btPersistentManifold::refreshContactPoints
// recomputes the world points and separations from the body-fixed local points and drops points
// that separated beyond the breaking threshold. Accumulated impulses (warm starting) are kept.
// The recorded relative transform is only replaced by a full narrowphase, so the reused geometry
// is never further than `distance` from what the narrowphase would find now.
//
// Accuracy: a contact that appears while a pair is within `distance` of its recorded pose (a new
// corner touching) is found up to `distance` late (penetration up to ~`distance` before the full
// narrowphase runs); kept points are exact for the body-fixed points they track. Pairs with no
// manifold points are treated alike (they may start touching up to `distance` late).
// Thread-safety: none (the owning PhysicsWorld's thread). Cost: O(1) per pair per step, a
// 3x3 matrix product and one pass over the pair's (<= 4) points when reused.
#pragma once

#include <btBulletCollisionCommon.h>

#include <cstdint>

namespace edgephys::physics {

// Counters shared by the world's reuse algorithms.
struct ManifoldReuseStats {
  uint64_t full = 0;    // box-box narrowphase runs
  uint64_t reused = 0;  // box-box pairs whose manifold was reused instead
};

// Bullet create function for BOX x BOX; register with
// btCollisionDispatcher::registerCollisionCreateFunc(BOX_SHAPE_PROXYTYPE, BOX_SHAPE_PROXYTYPE, f).
// Must outlive the dispatcher's use of it (algorithms it created keep a pointer to `stats`).
class ManifoldReuseCreateFunc : public btCollisionAlgorithmCreateFunc {
 public:
  // `distance` (m, > 0): the largest relative motion for which a manifold is reused.
  explicit ManifoldReuseCreateFunc(btScalar distance) : distance_(distance) {}
  btCollisionAlgorithm* CreateCollisionAlgorithm(btCollisionAlgorithmConstructionInfo& ci,
                                                 const btCollisionObjectWrapper* body0,
                                                 const btCollisionObjectWrapper* body1) override;
  const ManifoldReuseStats& stats() const { return stats_; }

 private:
  btScalar distance_;
  ManifoldReuseStats stats_;
};

}  // namespace edgephys::physics
