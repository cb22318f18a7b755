// PhyS's contact solver: Bullet's solver with the response filter and patch friction (see
// contact_solver.h for the model and its bounds).
#include "physics_backend/contact_solver.h"

#include <BulletCollision/NarrowPhaseCollision/btPersistentManifold.h>
#include <BulletDynamics/Dynamics/btRigidBody.h>

#include <algorithm>
#include <cmath>
#include <type_traits>

namespace edgephys::physics::internal {
namespace {

// Whether the solver should see the manifold at all (Bullet's island path filters the same way:
// btCollisionDispatcher::needsResponse; pairs of two static/kinematic bodies are skipped later by
// Bullet's convertContact through their zero inverse masses).
bool Responds(const btPersistentManifold& m) {
  return m.getBody0()->hasContactResponse() && m.getBody1()->hasContactResponse();
}

// Bullet's row update (gResolveSingleConstraintRowGeneric_scalar_reference) without the clamp:
// the impulse change that would make the row's relative velocity its target.
btScalar UnclampedDelta(const btSolverConstraint& c, btSolverBody& a, btSolverBody& b) {
  btScalar d = c.m_rhs - c.m_appliedImpulse * c.m_cfm;
  d -= (c.m_contactNormal1.dot(a.internalGetDeltaLinearVelocity()) +
        c.m_relpos1CrossNormal.dot(a.internalGetDeltaAngularVelocity())) *
       c.m_jacDiagABInv;
  d -= (c.m_contactNormal2.dot(b.internalGetDeltaLinearVelocity()) +
        c.m_relpos2CrossNormal.dot(b.internalGetDeltaAngularVelocity())) *
       c.m_jacDiagABInv;
  return d;
}

void Apply(const btSolverConstraint& c, btSolverBody& a, btSolverBody& b, btScalar impulse) {
  a.internalApplyImpulse(c.m_contactNormal1 * a.internalGetInvMass(), c.m_angularComponentA,
                         impulse);
  b.internalApplyImpulse(c.m_contactNormal2 * b.internalGetInvMass(), c.m_angularComponentB,
                         impulse);
}

}  // namespace

template <class Base>
ContactSolver<Base>::ContactSolver(bool patch_friction)
    : patch_(patch_friction && std::is_same_v<Base, btSequentialImpulseConstraintSolver>) {}

template <class Base>
bool ContactSolver<Base>::PatchEligible(const btPersistentManifold& m) const {
  if (m.getNumContacts() == 0) return false;
  if (m.getBody0()->hasAnisotropicFriction() || m.getBody1()->hasAnisotropicFriction()) {
    return false;
  }
  for (int j = 0; j < m.getNumContacts(); ++j) {
    const btManifoldPoint& cp = m.getContactPoint(j);
    if (cp.m_combinedRollingFriction > 0 || cp.m_combinedSpinningFriction > 0) return false;
    if ((cp.m_contactPointFlags & BT_CONTACT_FLAG_FRICTION_ANCHOR) != 0) return false;
  }
  return true;
}

template <class Base>
void ContactSolver<Base>::convertContacts(btPersistentManifold** manifolds, int count,
                                          const btContactSolverInfo& info) {
  patches_.clear();
  twist_.resizeNoInitialize(0);
  for (int i = 0; i < count; ++i) {
    btPersistentManifold* m = manifolds[i];
    // A manifold without points adds no rows (Bullet's convertContact would only look up the two
    // solver bodies); pairs whose AABBs overlap but whose shapes do not touch keep such
    // manifolds, and testing the count first spares touching the two collision objects.
    if (m->getNumContacts() == 0 || !Responds(*m)) continue;
    if (patch_ && PatchEligible(*m)) {
      ConvertPatch(m, info);
    } else {
      this->convertContact(m, info);
    }
  }
}

template <class Base>
void ContactSolver<Base>::ConvertPatch(btPersistentManifold* m, const btContactSolverInfo& info) {
  auto* o0 = const_cast<btCollisionObject*>(m->getBody0());
  auto* o1 = const_cast<btCollisionObject*>(m->getBody1());
  const int id_a = this->getOrInitSolverBody(*o0, info.m_timeStep);
  const int id_b = this->getOrInitSolverBody(*o1, info.m_timeStep);
  {
    const btSolverBody& a = this->m_tmpSolverBodyPool[id_a];
    const btSolverBody& b = this->m_tmpSolverBodyPool[id_b];
    if (a.m_invMass.fuzzyZero() && b.m_invMass.fuzzyZero()) return;  // as Bullet
  }
  btConstraintArray& normals = this->m_tmpSolverContactConstraintPool;
  btConstraintArray& frictions = this->m_tmpSolverContactFrictionConstraintPool;
  const btVector3& origin_a = o0->getWorldTransform().getOrigin();
  const btVector3& origin_b = o1->getWorldTransform().getOrigin();

  Patch p{};
  p.first_normal = normals.size();
  p.manifold = m;
  btVector3 mids[MANIFOLD_CACHE_SIZE];
  btVector3 centre(0, 0, 0);
  btVector3 normal(0, 0, 0);
  btScalar mu = 0;
  btScalar relaxation = 1;
  btManifoldPoint* oldest = nullptr;
  for (int j = 0; j < m->getNumContacts() && p.normals < MANIFOLD_CACHE_SIZE; ++j) {
    btManifoldPoint& cp = m->getContactPoint(j);
    if (cp.getDistance() > m->getContactProcessingThreshold()) continue;
    btSolverConstraint& row = normals.expandNonInitializing();
    row.m_solverBodyIdA = id_a;
    row.m_solverBodyIdB = id_b;
    row.m_originalContactPoint = &cp;
    const btVector3 rel_a = cp.getPositionWorldOnA() - origin_a;
    const btVector3 rel_b = cp.getPositionWorldOnB() - origin_b;
    this->setupContactConstraint(row, id_a, id_b, cp, info, relaxation, rel_a, rel_b);
    mids[p.normals] = (cp.getPositionWorldOnA() + cp.getPositionWorldOnB()) * btScalar(0.5);
    centre += mids[p.normals];
    normal += cp.m_normalWorldOnB;
    mu += cp.m_combinedFriction;
    if (oldest == nullptr || cp.getLifeTime() > oldest->getLifeTime()) oldest = &cp;
    ++p.normals;
  }
  if (p.normals == 0) return;
  const btScalar inv_n = btScalar(1) / btScalar(p.normals);
  centre *= inv_n;
  p.mu = mu * inv_n;
  if (normal.length2() > SIMD_EPSILON) {
    normal.normalize();
  } else {
    normal = oldest->m_normalWorldOnB;
  }
  btScalar spread = 0;
  for (int j = 0; j < p.normals; ++j) spread += (mids[j] - centre).length();
  p.twist_radius = kTwistRadiusFactor * spread * inv_n;

  // Every normal row of the patch points at its first tangent row (Bullet's write-back stores
  // that row's impulse in each point's m_appliedImpulseLateral1).
  p.tangent = frictions.size();
  for (int j = 0; j < p.normals; ++j) normals[p.first_normal + j].m_frictionIndex = p.tangent;

  const btVector3 rel_a = centre - origin_a;
  const btVector3 rel_b = centre - origin_b;
  btVector3 t1, t2;
  btPlaneSpace1(normal, t1, t2);
  const bool warm = (info.m_solverMode & SOLVER_USE_WARMSTARTING) != 0;
  const btScalar start[2] = {warm ? oldest->m_appliedImpulseLateral1 * info.m_warmstartingFactor : 0,
                             warm ? oldest->m_appliedImpulseLateral2 * info.m_warmstartingFactor : 0};
  const btVector3* dirs[2] = {&t1, &t2};
  for (int k = 0; k < 2; ++k) {
    btSolverConstraint& f = this->addFrictionConstraint(*dirs[k], id_a, id_b, p.first_normal,
                                                        *oldest, rel_a, rel_b, o0, o1,
                                                        relaxation, info);
    f.m_friction = p.mu;
    f.m_appliedImpulse = start[k];
    if (start[k] != 0) {
      Apply(f, this->m_tmpSolverBodyPool[id_a], this->m_tmpSolverBodyPool[id_b], start[k]);
    }
  }

  p.twist = -1;
  if (p.twist_radius > 0) {
    btSolverConstraint& t = twist_.expandNonInitializing();
    t.m_frictionIndex = p.first_normal;
    this->setupTorsionalFrictionConstraint(t, normal, id_a, id_b, *oldest, p.mu * p.twist_radius,
                                           rel_a, rel_b, o0, o1, relaxation);
    if (std::isfinite(t.m_jacDiagABInv) && t.m_jacDiagABInv > 0) {
      p.twist = twist_.size() - 1;
    } else {
      twist_.pop_back();  // no rotational freedom about the normal
    }
  }
  patches_.push_back(p);
}

template <class Base>
btScalar ContactSolver<Base>::SolvePatch(Patch& p) {
  btScalar load = 0;
  const btConstraintArray& normals = this->m_tmpSolverContactConstraintPool;
  for (int j = 0; j < p.normals; ++j) load += normals[p.first_normal + j].m_appliedImpulse;
  if (!(load > 0)) return 0;  // as Bullet: no friction without a pushing normal impulse
  btSolverConstraint& c1 = this->m_tmpSolverContactFrictionConstraintPool[p.tangent];
  btSolverConstraint& c2 = this->m_tmpSolverContactFrictionConstraintPool[p.tangent + 1];
  btSolverBody& a = this->m_tmpSolverBodyPool[c1.m_solverBodyIdA];
  btSolverBody& b = this->m_tmpSolverBodyPool[c1.m_solverBodyIdB];
  // Both tangent rows from the same velocities, then the pair clamped to the friction disk.
  btScalar l1 = c1.m_appliedImpulse + UnclampedDelta(c1, a, b);
  btScalar l2 = c2.m_appliedImpulse + UnclampedDelta(c2, a, b);
  const btScalar limit = p.mu * load;
  const btScalar len2 = l1 * l1 + l2 * l2;
  if (len2 > limit * limit) {
    const btScalar s = limit / std::sqrt(len2);
    l1 *= s;
    l2 *= s;
  }
  const btScalar d1 = l1 - c1.m_appliedImpulse;
  const btScalar d2 = l2 - c2.m_appliedImpulse;
  c1.m_appliedImpulse = l1;
  c2.m_appliedImpulse = l2;
  Apply(c1, a, b, d1);
  Apply(c2, a, b, d2);
  const btScalar r1 = d1 / c1.m_jacDiagABInv;
  const btScalar r2 = d2 / c2.m_jacDiagABInv;
  btScalar residual = std::max(r1 * r1, r2 * r2);
  if (p.twist >= 0) {
    btSolverConstraint& t = twist_[p.twist];
    const btScalar torque_limit = t.m_friction * load;  // mu * r * load
    t.m_lowerLimit = -torque_limit;
    t.m_upperLimit = torque_limit;
    const btScalar r = this->resolveSingleConstraintRowGeneric(a, b, t);
    residual = std::max(residual, r * r);
  }
  return residual;
}

template <class Base>
btScalar ContactSolver<Base>::solveSingleIteration(int iteration, btCollisionObject** bodies,
                                                   int num_bodies, btPersistentManifold** manifolds,
                                                   int num_manifolds,
                                                   btTypedConstraint** constraints,
                                                   int num_constraints,
                                                   const btContactSolverInfo& info,
                                                   btIDebugDraw* debug) {
  if (!patch_ || patches_.empty()) {
    return Base::solveSingleIteration(iteration, bodies, num_bodies, manifolds, num_manifolds,
                                      constraints, num_constraints, info, debug);
  }
  // Bullet's iteration (joints, every normal row, rolling friction) with the friction pool
  // hidden, then here: Bullet's per-point friction rows of the other manifolds, and the patches'
  // tangent and twist rows.
  btConstraintArray& frictions = this->m_tmpSolverContactFrictionConstraintPool;
  const int rows = frictions.size();
  frictions.resizeNoInitialize(0);
  btScalar residual = Base::solveSingleIteration(iteration, bodies, num_bodies, manifolds,
                                                 num_manifolds, constraints, num_constraints, info,
                                                 debug);
  frictions.resizeNoInitialize(rows);  // capacity unchanged: the rows are still there
  if (iteration >= info.m_numIterations) return residual;  // joints-only extra iterations
  size_t next = 0;
  for (int j = 0; j < rows; ++j) {
    if (next < patches_.size() && patches_[next].tangent == j) {
      residual = std::max(residual, SolvePatch(patches_[next]));
      ++next;
      ++j;  // its second tangent row
      continue;
    }
    btSolverConstraint& row = frictions[j];
    const btScalar load = this->m_tmpSolverContactConstraintPool[row.m_frictionIndex].m_appliedImpulse;
    if (load > 0) {
      row.m_lowerLimit = -(row.m_friction * load);
      row.m_upperLimit = row.m_friction * load;
      const btScalar r = this->resolveSingleConstraintRowGeneric(
          this->m_tmpSolverBodyPool[row.m_solverBodyIdA],
          this->m_tmpSolverBodyPool[row.m_solverBodyIdB], row);
      residual = std::max(residual, r * r);
    }
  }
  return residual;
}

template <class Base>
btScalar ContactSolver<Base>::solveGroupCacheFriendlyFinish(btCollisionObject** bodies,
                                                            int num_bodies,
                                                            const btContactSolverInfo& info) {
  if (patch_ && (info.m_solverMode & SOLVER_USE_WARMSTARTING) != 0) {
    // Every point carries the patch's tangent impulses (the next step starts from its oldest).
    const btConstraintArray& normals = this->m_tmpSolverContactConstraintPool;
    const btConstraintArray& frictions = this->m_tmpSolverContactFrictionConstraintPool;
    for (const Patch& p : patches_) {
      const btScalar l1 = frictions[p.tangent].m_appliedImpulse;
      const btScalar l2 = frictions[p.tangent + 1].m_appliedImpulse;
      for (int j = 0; j < p.normals; ++j) {
        auto* pt = static_cast<btManifoldPoint*>(normals[p.first_normal + j].m_originalContactPoint);
        pt->m_appliedImpulseLateral1 = l1;
        pt->m_appliedImpulseLateral2 = l2;
      }
    }
  }
  patches_.clear();
  twist_.resizeNoInitialize(0);
  return Base::solveGroupCacheFriendlyFinish(bodies, num_bodies, info);
}

template class ContactSolver<btSequentialImpulseConstraintSolver>;
template class ContactSolver<btNNCGConstraintSolver>;

}  // namespace edgephys::physics::internal
