#!/usr/bin/env python3
"""Splits `perf script` samples (with call graphs) of the PhyS / raw-Bullet step into phases.

Usage: perf_phase_split.py PERF_SCRIPT_TEXT [ROOT_FRAME_SUBSTRING]
  e.g. ... prof.txt 'TimeStep<edgephys::physics::PhysSMultiObjectScene>'  (PhyS's steps only)
       ... prof.txt 'TimeStep<edgephys::physics::RawBulletMultiObjectScene>'  (raw Bullet's)
Input: `perf script -F comm,tid,ip,sym --no-inline` of a `perf record --call-graph dwarf` run of
bench/physics_cost_report (docs/benchmarks.md, "PhyS's own step cost, session 13").
A sample under convexSweepTest / createPredictiveContacts counts as CCD; any other sample is
attributed by walking its stack from the leaf up to the first frame that names a phase (Bullet's
static helpers show as [unknown] and go to their caller). malloc/free count as malloc wherever
they are called from; the caller phases are listed below the table."""
import re, sys, collections

# (phase, regex on the symbol); first match wins, leaf first.
RULES = [
  ("malloc", r"^(malloc|free|_int_malloc|_int_free|cfree|__libc_malloc|__libc_free|malloc_consolidate|operator new|operator delete|btAlignedAllocDefault|btAlignedFreeDefault|btAlignedAllocInternal|btAlignedFreeInternal|_int_realloc|realloc|unlink_chunk|tcache)"),
  ("phys:contact_diff", r"DiffContacts|PairKey|Touching"),
  ("phys:rest_manager", r"RestManager|FrozenCollector|MovingNeighbour|KinematicReaches"),
  ("phys:guard", r"RunGuard|CheckRigid|ResetRigid|RunSoftGuard"),
  ("phys:state_output", r"CollectStates|ReportTree|DrainEvents|ToState|SameState"),
  ("phys:motion_state", r"EntityMotionState"),
  ("phys:commands", r"ApplyCommands|MoveToTransform|StirrerPose|PhysSMultiObjectScene::Step"),
  ("phys:own_solver", r"ContactSolver|PatchFriction"),
  ("phys:tuned_aabb", r"TunedWorld.*updateAabbs"),
  ("ccd", r"createPredictiveContacts|convexSweepTest|btContinuousConvexCollision|btSubsimplexConvexCast|btConvexCast|ClosestNotMeConvexResultCallback|btSingleSweepCallback|objectQuerySingle|btGjkConvexCast|integrateTransformsInternal"),
  ("narrowphase", r"dBoxBox2|btBoxBoxDetector|btBoxBoxCollisionAlgorithm|defaultNearCallback|btManifoldResult|btPersistentManifold|btCollisionPairCallback|dispatchAllCollisionPairs|performDiscreteCollisionDetection|btConvexConvexAlgorithm|btGjk|btVoronoiSimplexSolver|btMinkowski|btPolyhedral|btConvexPlane|btCompound|getNewManifold|releaseManifold|findAlgorithm|btCollisionDispatcher|btBoxShape::localGetSupporting|getCacheEntry|refreshContactPoints|cullPoints|btCollisionAlgorithm"),
  ("broadphase", r"btAxisSweep3|btHashedOverlappingPairCache|btSortedOverlappingPairCache|btDbvt|btBroadphase|calculateOverlappingPairs|btOverlappingPairCache|btNullPairCache|setAabb|Handle::"),
  ("island", r"btSimulationIslandManager|btUnionFind|calculateSimulationIslands|updateActivationState|InplaceSolverIslandCallback|btSortConstraintOnIslandPredicate|btPersistentManifoldSortPredicate|buildIslands|findUnions|storeIslandActivationState|processIsland|btSimulationIslandManagerMt|solveConstraints"),
  ("solver_iterations", r"resolveSingleConstraintRow|resolveSplitPenetration|solveSingleIteration|solveGroupCacheFriendlyIterations|gResolve|resolveSingleConstraintRowGeneric|btSolverBody::|solveGroupCacheFriendlySplitImpulseIterations"),
  ("solver_setup_finish", r"btSequentialImpulseConstraintSolver|btNNCGConstraintSolver|solveGroupCacheFriendlySetup|convertContact|setupContactConstraint|setupFrictionConstraint|addFrictionConstraint|getOrInitSolverBody|initSolverBody|convertBodies|convertJoints|solveGroupCacheFriendlyFinish|writeBack|setFrictionConstraintImpulse|btSolverConstraint|restitutionCurve|applyAnisotropicFriction|btAlignedObjectArray<btSolverConstraint>|btPlaneSpace1|setupTorsional|addTorsional|solveGroup|prepareSolve|allSolved"),
  ("integrate_aabb", r"integrateTransforms|predictIntegratedTransform|btTransformUtil|predictUnconstraintMotion|applyDamping|synchronizeMotionStates|synchronizeSingleMotionState|updateAabbs|updateSingleAabb|getAabb|btTransformAabb|applyGravity|clearForces|saveKinematicState|proceedToTransform|setCenterOfMassTransform|updateInertiaTensor|integrateVelocities|btRigidBody::|btDefaultMotionState|internalSingleStepSimulation|btDiscreteDynamicsWorld::stepSimulation|btSoftRigidDynamicsWorld|btSoftBody|btDefaultSoftBodySolver|updateActions|updateVehicles|startProfiling|CProfile|btQuickprof|btClock"),
]
RX = [(n, re.compile(r)) for n, r in RULES]

def classify(sym):
  for n, r in RX:
    if r.search(sym):
      return n
  return None

def main(path, root=None):
  total = 0
  phase = collections.Counter()
  malloc_in = collections.Counter()
  unknown = collections.Counter()
  leaf_sym = collections.Counter()
  stack = []
  def flush():
    nonlocal total
    if not stack:
      return
    if root is not None and not any(root in f for f in stack):
      return
    total += 1
    leaf_sym[stack[0]] += 1
    ph = None
    saw_malloc = False
    if any(("convexSweepTest" in f or "createPredictiveContacts" in f) for f in stack):
      ph = "ccd"
      stack_walk = []
    else:
      stack_walk = stack
    for s in stack_walk:
      c = classify(s)
      if c == "malloc":
        saw_malloc = True
        continue
      if c is not None:
        ph = c
        break
    if ph is None:
      ph = "other"
      unknown[stack[0]] += 1
    if saw_malloc:
      malloc_in[ph] += 1
      phase["malloc"] += 1
    else:
      phase[ph] += 1
  for line in open(path, errors="replace"):
    if not line.strip():
      flush(); stack = []; continue
    if line[0] not in " \t":
      flush(); stack = []; continue
    parts = line.strip().split(None, 1)
    if len(parts) < 2:
      continue
    sym = parts[1]
    sym = re.sub(r"\s*\(.*\)$", "", sym) if sym.endswith(")") and " (" in sym else sym
    sym = re.sub(r"\+0x[0-9a-f]+$", "", sym)
    stack.append(sym)
  flush()
  print(f"samples {total}")
  for k, v in phase.most_common():
    extra = ""
    print(f"  {k:22s} {v:7d} {100.0*v/total:6.1f} %")
  print("malloc by caller phase:", ", ".join(f"{k} {100.0*v/total:.1f} %" for k, v in malloc_in.most_common()))
  print("top leaf symbols:")
  for k, v in leaf_sym.most_common(40):
    print(f"  {100.0*v/total:5.1f} %  {k[:110]}")
  print("unclassified leaves:")
  for k, v in unknown.most_common(15):
    print(f"  {100.0*v/total:5.1f} %  {k[:110]}")

main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None)
