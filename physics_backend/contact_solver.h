// Internal to physics/: PhyS's contact solver, Bullet's sequential impulse (or NNCG) solver with
// two changes a PhysicsConfig asks for (bullet_world.cc's NewSolver builds it only then; otherwise
// Bullet's own solver is used, bit for bit).
//
// 1. Response filter (always on in this class). Bullet's island manager hands the solver only the
//    manifolds that need a response (btCollisionDispatcher::needsResponse: both objects respond and
//    not both static/kinematic) when it splits islands, but with setSplitIslands(false) it hands it
//    EVERY manifold of the dispatcher, and btSequentialImpulseConstraintSolver::convertContact does
//    not check: a trigger (a non-responding object) then stops a body like a wall
//    (PhysicsConfig::split_islands = false, docs/benchmarks.md, "PhyS: cost"). The filter
//    skips those manifolds in both paths (in the split path it never finds one). O(manifolds).
//
// 2. Patch friction (PhysicsConfig::patch_friction; sequential impulse only, ignored with NNCG).
//    Instead of one or two friction rows per contact point, each manifold whose points all lie in
//    one contact patch gets, beside its normal rows (one per point, as Bullet):
//    - two tangent rows at the patch centre (the mean of the points), in a fixed tangent basis of
//      the mean normal (btPlaneSpace1), solved together and clamped to the friction DISK
//      |(l1, l2)| <= mu * (sum of the manifold's normal impulses) (isotropic Coulomb friction;
//      Bullet's per-point rows each clamp to mu times their own point's impulse, and two of them
//      form a box of up to sqrt(2) mu);
//    - one twist row about the normal, clamped to mu * r * (sum of normal impulses), where r is
//      kTwistRadiusFactor times the mean distance of the points from the centre: for a square
//      patch given by its four corners, 0.541 is exact for uniform pressure (torque mu N a 0.3826
//      for side a, corner distance a 0.7071), for a segment given by its two ends 0.5. So a box
//      spinning on its face slows as under uniform pressure (Bullet's per-point friction makes
//      the four corners carry everything: 1.85x that torque).
//    mu is the mean of the points' combined friction. Warm starting: every point of the manifold
//    carries the patch's tangent impulses in m_appliedImpulseLateral1/2 (Bullet keeps those when
//    it refreshes or replaces a point); the patch starts from those of its oldest point. The
//    twist row starts from zero each step. Rows per box pair with 4 points: 4 normal + 3 instead
//    of 4 + 4 (one row per point) or 4 + 8 (two per point).
//    Manifolds with rolling or spinning friction, or with friction anchors, keep Bullet's
//    per-point rows. SOLVER_INTERLEAVE_CONTACT_AND_FRICTION_CONSTRAINTS is ignored (patch rows are
//    solved after all normal rows of the iteration).
//    Accuracy: exact for flat patches (face-face, face-edge); for a patch whose normals differ
//    (never within one Bullet manifold of two convex shapes) the mean normal is used. Tested
//    against analytic slope, rest-on-slope and spin-down results (contact_solver_test.cc).
//
// Thread-safety: none (one PhysicsWorld's thread). Ownership: owned by PhysicsWorld like Bullet's
// solver. Cost: O(rows) per iteration, as Bullet; setup O(manifold points).
#pragma once

#include <BulletCollision/NarrowPhaseCollision/btPersistentManifold.h>
#include <BulletDynamics/ConstraintSolver/btNNCGConstraintSolver.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>

#include <vector>

namespace edgephys::physics::internal {

// r = kTwistRadiusFactor * mean distance of the patch's points from its centre.
inline constexpr btScalar kTwistRadiusFactor = btScalar(0.541);
// Base: btSequentialImpulseConstraintSolver or btNNCGConstraintSolver.
template <class Base>
class ContactSolver final : public Base {
 public:
  // patch_friction: see the header comment (ignored unless Base is the sequential impulse solver).
  explicit ContactSolver(bool patch_friction);

 protected:
  void convertContacts(btPersistentManifold** manifolds, int count,
                       const btContactSolverInfo& info) override;
  btScalar solveSingleIteration(int iteration, btCollisionObject** bodies, int num_bodies,
                                btPersistentManifold** manifolds, int num_manifolds,
                                btTypedConstraint** constraints, int num_constraints,
                                const btContactSolverInfo& info, btIDebugDraw* debug) override;
  btScalar solveGroupCacheFriendlyFinish(btCollisionObject** bodies, int num_bodies,
                                         const btContactSolverInfo& info) override;

 private:
  struct Patch {
    int first_normal;  // rows [first_normal, first_normal + normals) of the contact pool
    int normals;
    int tangent;       // rows tangent, tangent + 1 of the friction pool
    int twist;         // row of twist_ (-1: none)
    btScalar mu;
    btScalar twist_radius;
    btPersistentManifold* manifold;
  };
  // Whether the manifold gets patch rows (otherwise Bullet's convertContact).
  bool PatchEligible(const btPersistentManifold& m) const;
  void ConvertPatch(btPersistentManifold* m, const btContactSolverInfo& info);
  btScalar SolvePatch(Patch& p);
  bool patch_;
  std::vector<Patch> patches_;
  btConstraintArray twist_;
};

}  // namespace edgephys::physics::internal
