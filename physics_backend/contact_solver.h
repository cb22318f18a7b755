// Internal to physics/: PhyS's contact solver, Bullet's sequential impulse (or NNCG) solver with
// two changes a PhysicsConfig asks for (bullet_world.cc's NewSolver builds it only then; otherwise
// Bullet's own solver is used, bit for bit).
//
// 1. Response filter (always on in this class). Bullet's island manager hands the solver only the
//    manifolds that need a response (btCollisionDispatcher::needsResponse: both objects respond and
//    not both static/kinematic) when it splits islands, but with setSplitIslands(false) it hands it
//    EVERY manifold of the dispatcher, and btSequentialImpulseConstraintSolver::convertContact does
//    not check: a trigger (a non-responding object) then stops a body like a wall
//    (PhysicsConfig::split_islands = false). The filter
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
//    Block solve (only with block_solve, PhysicsConfig::patch_block_solve, off by
//    default: it stops the creep below but let boxes escape the full stir): each iteration solves a patch's rows TOGETHER: the normal rows
//    as generalised rows at the centre (the normal impulse and up to two tilt moments about the
//    principal axes of the points' lever arms: 1 row for one point, 2 for an edge, 3 for a
//    face), the two tangent rows and the twist row; up to 6 unknowns, through the inverse of
//    their effective-mass matrix (built once per step). The change of the normal impulse and
//    tilts is spread over the points least-norm and added to their impulses (re-spreading
//    the totals instead moves impulse the model does not see). The block is
//    dropped for that iteration, and the patch's rows solved one by one as before (normal rows
//    by projected Gauss-Seidel, then the tangent pair and the twist), if a point would pull,
//    the friction leaves its disk, or a point's normal velocity does not end within
//    kPointTolerance of its target. That last check matters where the points
//    outnumber the generalised rows (a face's 4 points, 3 rows; nearly collinear points whose
//    tilt is dropped): the block then meets only a least-squares fit of the points' targets
//    and, without the check, pushed touching corners apart every iteration, which threw 248 of
//    2,000 boxes out of the full stir.
//    Why: with the rows solved one after the other, the centre's tangent rows and the corners'
//    normal rows trade rotation about the horizontal axes each iteration, and a never-sleeping
//    layer of touching boxes rocked with a growing amplitude and crept (2.1 mm in 5 s against
//    Bullet's 0.01 mm). A resting box's
//    patch is never saturated, so its block solution is exact for that patch.
//    With the block solve a patch's normal rows are converted after all other manifolds' rows
//    and hidden from Bullet's loop (solved here only).
//    Manifolds with rolling or spinning friction, or with friction anchors, keep Bullet's
//    per-point rows. SOLVER_INTERLEAVE_CONTACT_AND_FRICTION_CONSTRAINTS is ignored (patch rows are
//    solved after all normal rows of the iteration).
//    Accuracy: exact for flat patches (face-face, face-edge); for a patch whose normals differ
//    (never within one Bullet manifold of two convex shapes) the mean normal is used. Tested
//    against analytic slope, rest-on-slope and spin-down results (contact_solver_test.cc).
//
// Thread-safety: none (one PhysicsWorld's thread). Ownership: owned by PhysicsWorld like Bullet's
// solver. Cost: O(rows) per iteration, as Bullet; setup O(manifold points), plus per patch and
// step a 6 x 6 matrix built and inverted (~1,000 flops), and per iteration a 6 x 6 product.
#pragma once

#include <BulletCollision/NarrowPhaseCollision/btPersistentManifold.h>
#include <BulletDynamics/ConstraintSolver/btNNCGConstraintSolver.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>

#include <vector>

namespace edgephys::physics::internal {

// r = kTwistRadiusFactor * mean distance of the patch's points from its centre.
inline constexpr btScalar kTwistRadiusFactor = btScalar(0.541);
// Block solve: a tilt row is kept only if its principal moment of the points' lever arms is
// more than this fraction of their sum (below it, nearly collinear points: the tilt is dropped
// and the points check below decides). 1e-3 lets ill-conditioned 3-point blocks
// through (boxes escape the full stir).
inline constexpr btScalar kTiltEigenFraction = btScalar(0.05);
// Block solve: a block is kept only if every point's normal velocity ends within this of its
// row's target (m/s); otherwise the patch is solved one row at a time that iteration.
inline constexpr btScalar kPointTolerance = btScalar(0.003);

// Base: btSequentialImpulseConstraintSolver or btNNCGConstraintSolver.
template <class Base>
class ContactSolver final : public Base {
 public:
  // patch_friction: see the header comment (ignored unless Base is the sequential impulse solver).
  // block_solve: patches solved as blocks (PhysicsConfig::patch_block_solve); without it every
  // patch is solved one row at a time.
  explicit ContactSolver(bool patch_friction, bool block_solve = false);

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
  // The patch's rows solved as one block (see SolveBlock): generalised rows at the patch centre
  // (normal, up to two tilts, two tangents, twist) mapped onto the solver's rows.
  struct Block {
    static constexpr int kMaxPoints = MANIFOLD_CACHE_SIZE;
    static constexpr int kMaxGen = 6;
    int pressure = 0;  // generalised normal rows: 1 + tilts (0: no block solve)
    int gen = 0;       // pressure + 2 tangents (+ 1 twist)
    // Corner impulse distribution of the generalised normal impulses: f_i = sum_k h[i][k] g_k
    // (least-norm), and the generalised impulses of corner impulses: g_k = sum_i lever[k][i] f_i.
    btScalar h[kMaxPoints][3];
    btScalar lever[3][kMaxPoints];
    btScalar target[kMaxPoints + 3];  // velocity each row aims at (rhs / jacDiagABInv)
    btScalar inverse[kMaxGen][kMaxGen];  // inverse of the generalised rows' effective mass
    btScalar response[kMaxPoints][kMaxGen];  // point i's normal velocity per unit impulse g
  };
  struct Patch {
    int first_normal;  // rows [first_normal, first_normal + normals) of the contact pool
    int normals;
    int tangent;       // rows tangent, tangent + 1 of the friction pool
    int twist;         // row of twist_ (-1: none)
    btScalar mu;
    btScalar twist_radius;
    btPersistentManifold* manifold;
    Block block;
  };
  // Whether the manifold gets patch rows (otherwise Bullet's convertContact).
  bool PatchEligible(const btPersistentManifold& m) const;
  void ConvertPatch(btPersistentManifold* m, const btContactSolverInfo& info);
  btScalar SolvePatch(Patch& p);
  // Points rows at the patch's rows in block order (normals, two tangents, the twist if any);
  // returns how many (at most Block::kMaxPoints + 3).
  int PatchRows(const Patch& p, btSolverConstraint** rows);
  // Sets up p.block from the patch's rows (after ConvertPatch added them).
  void SetupBlock(Patch& p, const btVector3& centre, const btVector3& normal,
                  const btVector3& t1, const btVector3& t2, const btVector3* mids);
  // Solves the patch's normal, tangent and twist rows together; false (nothing applied) when
  // the unclamped solution leaves the friction cone or pulls at a point.
  bool SolveBlock(Patch& p, btScalar* residual);

  bool patch_;
  bool block_;
  int patch_rows_ = 0;  // first contact-pool row Bullet's loop does not solve (patches' rows)
  std::vector<btPersistentManifold*> deferred_;  // patch manifolds, converted after the others
  std::vector<Patch> patches_;
  btConstraintArray twist_;
};

}  // namespace edgephys::physics::internal
