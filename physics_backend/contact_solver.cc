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

// The row's relative velocity from the bodies' velocity changes so far (Bullet's sign).
btScalar RowVelocity(const btSolverConstraint& c, btSolverBody& a, btSolverBody& b) {
  return c.m_contactNormal1.dot(a.internalGetDeltaLinearVelocity()) +
         c.m_relpos1CrossNormal.dot(a.internalGetDeltaAngularVelocity()) +
         c.m_contactNormal2.dot(b.internalGetDeltaLinearVelocity()) +
         c.m_relpos2CrossNormal.dot(b.internalGetDeltaAngularVelocity());
}

// What a unit impulse on a row does to the two bodies' velocities (internalApplyImpulse).
struct Effect {
  btVector3 lin_a, ang_a, lin_b, ang_b;
};
Effect UnitEffect(const btSolverConstraint& c, const btSolverBody& a, const btSolverBody& b) {
  return {c.m_contactNormal1 * a.m_invMass * a.m_linearFactor, c.m_angularComponentA * a.m_angularFactor,
          c.m_contactNormal2 * b.m_invMass * b.m_linearFactor, c.m_angularComponentB * b.m_angularFactor};
}

// In-place inverse of the symmetric positive definite n x n matrix m (Cholesky); false when it
// is not (numerically) positive definite.
template <int N>
bool InvertSpd(btScalar (&m)[N][N], int n) {
  btScalar l[N][N] = {};
  for (int j = 0; j < n; ++j) {
    btScalar d = m[j][j];
    for (int k = 0; k < j; ++k) d -= l[j][k] * l[j][k];
    if (!(d > btScalar(1e-9) * std::abs(m[j][j])) || !(d > 0)) return false;
    l[j][j] = std::sqrt(d);
    for (int i = j + 1; i < n; ++i) {
      btScalar s = m[i][j];
      for (int k = 0; k < j; ++k) s -= l[i][k] * l[j][k];
      l[i][j] = s / l[j][j];
    }
  }
  // inverse(L), lower triangular
  btScalar li[N][N] = {};
  for (int j = 0; j < n; ++j) {
    li[j][j] = 1 / l[j][j];
    for (int i = j + 1; i < n; ++i) {
      btScalar s = 0;
      for (int k = j; k < i; ++k) s -= l[i][k] * li[k][j];
      li[i][j] = s / l[i][i];
    }
  }
  // inverse(m) = inverse(L)^T inverse(L)
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j) {
      btScalar s = 0;
      for (int k = i; k < n; ++k) s += li[k][i] * li[k][j];
      m[i][j] = s;
      m[j][i] = s;
    }
  }
  return true;
}

}  // namespace

template <class Base>
ContactSolver<Base>::ContactSolver(bool patch_friction, bool block_solve)
    : patch_(patch_friction && std::is_same_v<Base, btSequentialImpulseConstraintSolver>),
      block_(patch_ && block_solve) {}

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
      if (block_) {
        deferred_.push_back(m);
      } else {
        ConvertPatch(m, info);
      }
    } else {
      this->convertContact(m, info);
    }
  }
  // Block solve: patches last, rows [patch_rows_, size) of the contact pool are their normal
  // rows, solved in solveSingleIteration (block or one by one), not by Bullet's loop.
  patch_rows_ = this->m_tmpSolverContactConstraintPool.size();
  for (btPersistentManifold* m : deferred_) ConvertPatch(m, info);
  deferred_.clear();
  if (!block_) patch_rows_ = this->m_tmpSolverContactConstraintPool.size();
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
  SetupBlock(p, centre, normal, t1, t2, mids);
  patches_.push_back(p);
}

template <class Base>
int ContactSolver<Base>::PatchRows(const Patch& p, btSolverConstraint** rows) {
  btConstraintArray& normals = this->m_tmpSolverContactConstraintPool;
  btConstraintArray& frictions = this->m_tmpSolverContactFrictionConstraintPool;
  int count = 0;
  for (int i = 0; i < p.normals; ++i) rows[count++] = &normals[p.first_normal + i];
  rows[count++] = &frictions[p.tangent];
  rows[count++] = &frictions[p.tangent + 1];
  if (p.twist >= 0) rows[count++] = &twist_[p.twist];
  return count;
}

template <class Base>
void ContactSolver<Base>::SetupBlock(Patch& p, const btVector3& centre, const btVector3& normal,
                                     const btVector3& t1, const btVector3& t2,
                                     const btVector3* mids) {
  Block& k = p.block;
  k.pressure = 0;
  k.gen = 0;
  if (!block_) return;
  const int n = p.normals;
  // Lever arms of the points about the centre, in the tangent basis; their principal axes are
  // the tilt axes (the mean of the points is the centre, so the lever arms sum to zero).
  btScalar g1[Block::kMaxPoints], g2[Block::kMaxPoints];
  btScalar s11 = 0, s12 = 0, s22 = 0;
  for (int i = 0; i < n; ++i) {
    const btVector3 d = (mids[i] - centre).cross(normal);
    g1[i] = d.dot(t1);
    g2[i] = d.dot(t2);
    s11 += g1[i] * g1[i];
    s12 += g1[i] * g2[i];
    s22 += g2[i] * g2[i];
  }
  const btScalar angle = btScalar(0.5) * std::atan2(2 * s12, s11 - s22);
  const btScalar c = std::cos(angle), s = std::sin(angle);
  const btScalar axes[2][2] = {{c, s}, {-s, c}};
  const btScalar eig[2] = {s11 * c * c + 2 * s12 * s * c + s22 * s * s,
                           s11 * s * s - 2 * s12 * s * c + s22 * c * c};
  const btScalar trace = s11 + s22;
  const btScalar inv_n = btScalar(1) / btScalar(n);
  int pressure = 1;
  for (int i = 0; i < n; ++i) {
    k.lever[0][i] = 1;
    k.h[i][0] = inv_n;
  }
  for (int a = 0; a < 2 && n > 1; ++a) {
    if (!(eig[a] > kTiltEigenFraction * trace) || !(eig[a] > btScalar(1e-10))) continue;
    for (int i = 0; i < n; ++i) {
      k.lever[pressure][i] = g1[i] * axes[a][0] + g2[i] * axes[a][1];
      k.h[i][pressure] = k.lever[pressure][i] / eig[a];
    }
    ++pressure;
  }
  // The patch's rows: normals, two tangents, the twist; T maps generalised impulses onto them.
  btSolverConstraint* rows[Block::kMaxPoints + 3];
  const int count = PatchRows(p, rows);
  const int gen = pressure + 2 + (p.twist >= 0 ? 1 : 0);
  btScalar t[Block::kMaxPoints + 3][Block::kMaxGen] = {};
  for (int i = 0; i < n; ++i) {
    for (int g = 0; g < pressure; ++g) t[i][g] = k.h[i][g];
  }
  for (int r = n; r < count; ++r) t[r][pressure + (r - n)] = 1;
  for (int r = 0; r < count; ++r) {
    const btSolverConstraint& row = *rows[r];
    if (row.m_cfm != 0 || !(row.m_jacDiagABInv > 0) || !std::isfinite(row.m_jacDiagABInv)) return;
    k.target[r] = row.m_rhs / row.m_jacDiagABInv;
  }
  const btSolverBody& a = this->m_tmpSolverBodyPool[rows[0]->m_solverBodyIdA];
  const btSolverBody& b = this->m_tmpSolverBodyPool[rows[0]->m_solverBodyIdB];
  // Each generalised row's Jacobian and the effect of a unit impulse on it (sums of the rows');
  // its effective-mass matrix is m[g][d] = jacobian[g] . effect[d].
  Effect eff[Block::kMaxGen];
  Effect jac[Block::kMaxGen];
  const btVector3 zero(0, 0, 0);
  for (int g = 0; g < gen; ++g) {
    eff[g] = {zero, zero, zero, zero};
    jac[g] = {zero, zero, zero, zero};
  }
  for (int r = 0; r < count; ++r) {
    const btSolverConstraint& row = *rows[r];
    const Effect e = UnitEffect(row, a, b);
    for (int g = 0; g < gen; ++g) {
      const btScalar w = t[r][g];
      if (w == 0) continue;
      eff[g].lin_a += e.lin_a * w;
      eff[g].ang_a += e.ang_a * w;
      eff[g].lin_b += e.lin_b * w;
      eff[g].ang_b += e.ang_b * w;
      jac[g].lin_a += row.m_contactNormal1 * w;
      jac[g].ang_a += row.m_relpos1CrossNormal * w;
      jac[g].lin_b += row.m_contactNormal2 * w;
      jac[g].ang_b += row.m_relpos2CrossNormal * w;
    }
  }
  btScalar m[Block::kMaxGen][Block::kMaxGen];
  for (int g = 0; g < gen; ++g) {
    for (int d = g; d < gen; ++d) {
      // symmetric up to rounding: average the two products
      const btScalar v =
          btScalar(0.5) * (jac[g].lin_a.dot(eff[d].lin_a) + jac[g].ang_a.dot(eff[d].ang_a) +
                           jac[g].lin_b.dot(eff[d].lin_b) + jac[g].ang_b.dot(eff[d].ang_b) +
                           jac[d].lin_a.dot(eff[g].lin_a) + jac[d].ang_a.dot(eff[g].ang_a) +
                           jac[d].lin_b.dot(eff[g].lin_b) + jac[d].ang_b.dot(eff[g].ang_b));
      m[g][d] = v;
      m[d][g] = v;
    }
  }
  // What a unit generalised impulse does to each point's normal velocity (the points check).
  for (int i = 0; i < n; ++i) {
    const btSolverConstraint& row = *rows[i];
    for (int g = 0; g < gen; ++g) {
      k.response[i][g] = row.m_contactNormal1.dot(eff[g].lin_a) +
                         row.m_relpos1CrossNormal.dot(eff[g].ang_a) +
                         row.m_contactNormal2.dot(eff[g].lin_b) +
                         row.m_relpos2CrossNormal.dot(eff[g].ang_b);
    }
  }
  if (!InvertSpd(m, gen)) return;
  for (int g = 0; g < gen; ++g) {
    for (int d = 0; d < gen; ++d) k.inverse[g][d] = m[g][d];
  }
  k.pressure = pressure;
  k.gen = gen;
}

template <class Base>
bool ContactSolver<Base>::SolveBlock(Patch& p, btScalar* residual) {
  Block& k = p.block;
  if (k.pressure == 0) return false;
  const int n = p.normals;
  btSolverConstraint* rows[Block::kMaxPoints + 3];
  const int count = PatchRows(p, rows);
  btSolverBody& a = this->m_tmpSolverBodyPool[rows[0]->m_solverBodyIdA];
  btSolverBody& b = this->m_tmpSolverBodyPool[rows[0]->m_solverBodyIdB];
  btScalar e[Block::kMaxPoints + 3];
  for (int r = 0; r < count; ++r) e[r] = k.target[r] - RowVelocity(*rows[r], a, b);
  btScalar rhs[Block::kMaxGen];
  for (int g = 0; g < k.pressure; ++g) {
    btScalar v = 0;
    for (int i = 0; i < n; ++i) v += k.h[i][g] * e[i];
    rhs[g] = v;
  }
  for (int r = n; r < count; ++r) rhs[k.pressure + (r - n)] = e[r];
  btScalar y[Block::kMaxGen];
  for (int g = 0; g < k.gen; ++g) {
    btScalar v = 0;
    for (int d = 0; d < k.gen; ++d) v += k.inverse[g][d] * rhs[d];
    y[g] = v;
  }
  // Every point must end at its own target: with fewer generalised rows than points (a face's
  // 4 points, 3 rows) the block meets only a least-squares fit of the points' targets, which
  // pushed touching corners apart (boxes thrown out of the full stir).
  for (int i = 0; i < n; ++i) {
    btScalar v = e[i];
    for (int g = 0; g < k.gen; ++g) v -= k.response[i][g] * y[g];
    if (!(std::abs(v) <= kPointTolerance)) return false;
  }
  // The change of the generalised normal impulses, spread over the points (least-norm) and
  // added to each point's impulse: every point pushes.
  btScalar f[Block::kMaxPoints];
  btScalar load = 0;
  for (int i = 0; i < n; ++i) {
    btScalar v = rows[i]->m_appliedImpulse;
    for (int g = 0; g < k.pressure; ++g) v += k.h[i][g] * y[g];
    if (!(v >= 0)) return false;
    f[i] = v;
    load += v;
  }
  btScalar fr[3];
  for (int r = n; r < count; ++r) fr[r - n] = rows[r]->m_appliedImpulse + y[k.pressure + (r - n)];
  const btScalar limit = p.mu * load;
  if (fr[0] * fr[0] + fr[1] * fr[1] > limit * limit) return false;
  if (p.twist >= 0 && std::abs(fr[2]) > rows[n + 2]->m_friction * load) return false;
  btScalar worst = 0;
  for (int r = 0; r < count; ++r) {
    const btScalar now = r < n ? f[r] : fr[r - n];
    const btScalar d = now - rows[r]->m_appliedImpulse;
    rows[r]->m_appliedImpulse = now;
    if (d != 0) Apply(*rows[r], a, b, d);
    worst = std::max(worst, d * d);
  }
  *residual = worst;
  return true;
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
  // Bullet's iteration (joints, the other manifolds' normal rows, rolling friction) with the
  // friction pool and the patches' normal rows hidden, then here: Bullet's per-point friction
  // rows of the other manifolds, and the patches (all rows of each, block or one by one).
  btConstraintArray& frictions = this->m_tmpSolverContactFrictionConstraintPool;
  btConstraintArray& contacts = this->m_tmpSolverContactConstraintPool;
  const int rows = frictions.size();
  const int contact_rows = contacts.size();
  frictions.resizeNoInitialize(0);
  contacts.resizeNoInitialize(patch_rows_);
  btScalar residual = Base::solveSingleIteration(iteration, bodies, num_bodies, manifolds,
                                                 num_manifolds, constraints, num_constraints, info,
                                                 debug);
  frictions.resizeNoInitialize(rows);  // capacity unchanged: the rows are still there
  contacts.resizeNoInitialize(contact_rows);
  if (iteration >= info.m_numIterations) return residual;  // joints-only extra iterations
  size_t next = 0;
  for (int j = 0; j < rows; ++j) {
    if (next < patches_.size() && patches_[next].tangent == j) {
      btScalar r = 0;
      Patch& p = patches_[next];
      if (!SolveBlock(p, &r)) {
        // One by one: the normal rows if hidden from Bullet's loop, then the friction rows.
        for (int i = 0; p.first_normal >= patch_rows_ && i < p.normals; ++i) {
          const btSolverConstraint& c = contacts[p.first_normal + i];
          const btScalar n = this->resolveSingleConstraintRowLowerLimit(
              this->m_tmpSolverBodyPool[c.m_solverBodyIdA],
              this->m_tmpSolverBodyPool[c.m_solverBodyIdB], c);
          r = std::max(r, n * n);
        }
        r = std::max(r, SolvePatch(p));
      }
      residual = std::max(residual, r);
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
