// PhysicsWorld: one Bullet world for one room (PhyS). It builds Bullet objects
// from the dissected containers (schema/container.fbs), advances the simulation in fixed steps,
// reports moved entities, collision/trigger events and stability-guard resets.
//
// Thread-safety: none. A PhysicsWorld is owned and used by exactly one thread (the room's thread).
//   Debian's Bullet is built without BT_THREADSAFE; different PhysicsWorld instances share no
//   mutable state and may run on different threads concurrently.
// Ownership: the world owns every Bullet object it creates. Containers passed to AddEntity are
//   only read during the call (nothing keeps pointers into the flatbuffer).
// Units: metres, seconds, kilograms, radians; room frame, Y up (gravity configurable).
// Failure: every command returns a Status; invalid input never changes the world.
// Cost: Step() is one Bullet step plus O(active bodies + contact manifolds + commands since the
//   last step); sleeping bodies cost nothing beyond what Bullet itself spends on them, and
//   frozen (resting) bodies likewise (PhysicsConfig::rest_freeze; plus O(broadphase pairs), or
//   O(frozen bodies * log n) when they are few, for the wake check while any are frozen).
//   Step(), CollectStates() and DrainEvents() do not allocate in steady state (vectors are
//   reused and only grow).
//
// What the builder supports (the contract with client dissection):
//   - Transform-only entities (no rigid body, colliders, soft body): hierarchy nodes. If such an
//     entity has a parent, it keeps its pose relative to the parent and follows it whenever the
//     parent moves (any depth of transform-only descendants). Entities with physics are simulated
//     in the room frame; their parent id is stored but does not constrain them (as in Unity, a
//     non-kinematic body under a moving parent is independent). Parents must be added before
//     their children (kUnknownParent otherwise).
//   - Colliders: box, sphere, capsule (Y axis, height between cap centres), cylinder (Y axis),
//     convex hull, triangle mesh, each with a local offset; several -> btCompoundShape. The body
//     origin is the entity origin and is used as the centre of mass (compound inertia is Bullet's
//     bounding-box approximation). Transform scale multiplies dimensions, offsets and vertices
//     (spheres/capsule radii use the largest scale component).
//   - Triangle meshes are exact (btBvhTriangleMeshShape) on static and kinematic entities. On
//     dynamic entities they are replaced by the convex hull of their vertices; a client that
//     needs concave dynamic bodies should send a convex decomposition (several ConvexHull
//     colliders).
//   - Triggers (is_trigger): a separate non-responding collision object following the entity, so
//     an entity may mix solid and trigger colliders (e.g. a hand). Triggers report
//     kTriggerEnter/Exit against dynamic bodies only (static and kinematic bodies share Bullet's
//     static filter group and are not paired with triggers). Trigger-trigger overlaps are ignored.
//   - Bodies: RigidBody.mass > 0 and not kinematic -> dynamic; kinematic flag (RigidBody.kinematic
//     or EntityFlags::Kinematic) -> kinematic (never sleeps, moved by MoveToTransform); colliders
//     without a rigid body, or mass 0 and not kinematic -> static.
//   - Friction and restitution are combined the Bullet way: the product of both bodies' values.
//   - Joints: Fixed (btFixedConstraint), Hinge (btHingeConstraint, axis in the entity frame),
//     Spring (btGeneric6DofSpring2Constraint: three linear springs with `stiffness` N/m and
//     `damping`, angular axes free). `anchor` is in the entity's local frame; connected_entity 0
//     means the world, otherwise it must already exist and have a rigid body. The joint is built
//     in the current pose (the current relative pose is the rest pose). Removing either entity
//     removes the joint.
//   - Soft bodies: particles (room frame), per-particle masses (0 pins a particle), springs (index
//     pairs). `stiffness` is a spring constant in N/m; Bullet's position-based links get
//     kLST = stiffness * dt^2 * 2 / mean_particle_mass, clamped to
//     PhysicsConfig::soft_max_link_stiffness (<= 1 is unconditionally stable; > 2 diverges).
//     `damping` is Bullet's kDP in [0, 1]. Soft bodies collide with rigid bodies (SDF) but do not
//     produce collision events. A soft body entity ignores rigid_body and colliders.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string_view>
#include <unordered_map>
#include <span>
#include <vector>

#include "protocol/state_codec.h"
#include "protocol/status.h"

namespace edgephys::schema {
struct Container;
}  // namespace edgephys::schema

class btBroadphaseInterface;
class btCollisionConfiguration;
class btCollisionDispatcher;
class btCollisionObject;
class btCollisionShape;
class btConstraintSolver;
class btDiscreteDynamicsWorld;
class btRigidBody;
class btSoftBody;
class btSoftBodyWorldInfo;
class btTypedConstraint;

namespace edgephys::physics {

namespace internal {
struct BodyShapes;  // physics_world_internal.h
}  // namespace internal
class RestManager;  // rest_manager.h

inline constexpr float kBulletAabbMargin = 0.02f;  // Bullet's gContactBreakingThreshold

struct PhysicsConfig {
  float fixed_dt = 1.0f / 60.0f;      // seconds per Step()
  // Bullet steps per Step(), each of fixed_dt / substeps (kinematic targets are interpolated
  // across them). Cost: every substep is a full Bullet step, so Step() grows with substeps.
  // Tall stacks need more than 1 to stand (docs/benchmarks.md, "PhyS: accuracy and stability").
  int substeps = 1;
  // Sequential impulse iterations (per substep). With one friction row per contact (Bullet's
  // default) 7 keep the accuracy suite passing and 6 or 5 do not (the never-sleeping stack
  // creeps 0.29 / 0.27 m in 60 s, bound 0.25); with two cached friction rows (see
  // two_friction_directions) 4 hold it to 0.09 m. Each iteration is ~1.5-3 % of a 2,000-box
  // MultiObject step (docs/benchmarks.md, "Full stir, session 11").
  int solver_iterations = 7;
  int max_substeps = 4;               // Advance(): most fixed steps per call (backlog dropped)
  Vec3f gravity{0.0f, -9.81f, 0.0f};  // m/s^2
  bool soft_body_world = true;        // btSoftRigidDynamicsWorld; false: btDiscreteDynamicsWorld
                                      // and soft-body containers are rejected
  // Continuous collision detection: dynamic bodies sweep a sphere of ccd_swept_radius_fraction *
  // (smallest half extent) whenever they move more than ccd_motion_fraction * (smallest half
  // extent) in one step, i.e. only small fast bodies pay for it. On the full stir the sweeps
  // (8.2 % of the step) are what keeps boxes from being thrown out over the walls: their
  // predictive contacts between fast boxes, not those against walls (session 14, see
  // containment).
  bool ccd = true;
  // Measured at 1.0 (sweep only bodies that move more than their smallest half extent per
  // step): no step time saved within the noise at 2,000 boxes, and 1-4 of 2,000 stirred boxes
  // were squeezed out of the full-stir container where 0.5 kept all in, so 0.5 stays.
  float ccd_motion_fraction = 0.5f;
  float ccd_swept_radius_fraction = 0.9f;
  bool sleeping = true;               // false: bodies never deactivate
  // Below both for Bullet's 2 s deactivation time, the body (its island) sleeps. Higher values
  // let settled stacks sleep sooner but freeze slow damped motion before it settles.
  float sleep_linear_threshold = 0.1f;   // m/s
  float sleep_angular_threshold = 0.1f;  // rad/s
  float world_half_extent = 1000.0f;  // world bounds: axis-aligned cube, metres from the origin
  // --- What a scene does not need, PhyS does not compute. Each setting below was measured as
  // step time (2,000-box MultiObject) against the accuracy suite (docs/benchmarks.md, "PhyS:
  // model no more than the scene needs"); the defaults are the picks from that chart.
  // Seconds an island stays below both sleep thresholds before it sleeps (Bullet: 2 s, a
  // process-wide global; PhyS emulates other values per body, O(active bodies) per step).
  // Shorter: settled piles stop costing sooner; slow damped motion freezes sooner.
  float deactivation_time = 2.0f;
  // Broadphase. kDbvt (Bullet's default): dynamic AABB trees; every step re-finds the
  // overlaps of every moving body in a tree fattened by 5 cm and hashes them again.
  // kAxisSweep: bt32BitAxisSweep3 over the world bounds (the cube of world_half_extent):
  // sweep and prune, pairs change only when AABB ends pass each other, so coherent motion in a
  // bounded room is cheap; a teleport across the room costs O(objects). Its capacity starts at
  // 1,024 collision objects and doubles when AddEntity needs more (O(objects) once per
  // doubling; contacts are found again by the next step). ~150 bytes per capacity slot.
  enum class Broadphase : uint8_t { kDbvt, kAxisSweep };
  Broadphase broadphase = Broadphase::kAxisSweep;
  // Split impulse (Bullet's default: on): penetration is resolved by a separate position-only
  // pass, so it adds no energy; off folds it into the velocity (Baumgarte), one solver pass
  // fewer per iteration.
  // Off by default: the accuracy suite passes unchanged without it and the step is cheaper.
  bool split_impulse = false;
  // SOLVER_RANDMIZE_ORDER: shuffles the rows every iteration, so no contact is always solved
  // last. Holds a never-sleeping stack to 1.5 cm at 5 iterations, but the shuffle costs more
  // than the 5 iterations it saves (+10 % step time at 2,000 boxes), so it is off.
  bool randomize_solver_order = false;
  // Warm starting scales last step's impulses into the first iteration (Bullet's default
  // 0.85; 0 turns warm starting off).
  float warmstarting_factor = 0.85f;
  // The solver stops iterating when the squared residual falls below this (0: always
  // solver_iterations). Cost saved only when islands converge early.
  float solver_residual_threshold = 0.0f;
  // --- Solver and CCD settings measured on the full stir in session 11 (docs/benchmarks.md,
  // "Full stir, session 11"; --only names in bench/physics_cost_candidates.cc).
  // Constraint solver. kSequentialImpulse: Bullet's default (projected Gauss-Seidel).
  // kNNCG: btNNCGConstraintSolver (nonlinear conjugate gradient on top of the same rows;
  // meant to converge in fewer iterations, at extra work per iteration). Measured: at 7
  // iterations the never-sleeping stack holds to 0.03 m but a restitution or stick-slip bound
  // fails; at 5 the stack collapses. Not the default.
  enum class Solver : uint8_t { kSequentialImpulse, kNNCG };
  Solver solver = Solver::kSequentialImpulse;
  // Bullet's island manager sorts every contact manifold by island and calls the solver once
  // per island (batched up to 128 rows). false: one solver call with every body and manifold,
  // no sorting; sleeping islands still sleep (islands are still built for that).
  // Measured (full stir): false saves about 3 % of the step; the default since session 12
  // (docs/benchmarks.md, "Full stir, session 12"). Bullet then hands the solver every
  // manifold, trigger pairs included (it filters them only per island), so PhyS's ContactSolver
  // (contact_solver.h) skips pairs that need no response; before session 12 a trigger stopped a
  // body like a wall with this off (the two trigger tests that failed in "Full stir, session 11").
  bool split_islands = false;
  // Friction rows per contact point: Bullet's default is one, along the sliding direction.
  // two_friction_directions adds the orthogonal one (SOLVER_USE_2_FRICTION_DIRECTIONS);
  // friction_direction_caching keeps a contact's directions from the step that created it
  // (SOLVER_ENABLE_FRICTION_DIRECTION_CACHING; Bullet reuses them only together with
  // two_friction_directions and velocity_dependent_friction = false).
  // Measured: two cached rows in a fixed tangent basis cost more rows per iteration but converge
  // much better (never-sleeping stack 0.04 m against 0.16 m at 7 iterations), so 4 iterations
  // pass the report's suite experiments where one row needs 7: ~6 % less per step. (Bullet keeps
  // the cached directions only until btPersistentManifold::replaceContactPoint rewrites a point,
  // i.e. box-box points get fresh ones every step.) With manifold reuse on, a resting pile ends
  // 7.7 mm off the run without reuse (ManifoldReuseTest's bound: 2 mm; clearing the cache of
  // reused points did not help), see "Full stir, session 12".
  bool two_friction_directions = false;
  bool friction_direction_caching = false;
  // true (Bullet's default): the first friction direction follows the relative sliding
  // velocity; false: a fixed tangent basis (SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION).
  bool velocity_dependent_friction = true;
  // SOLVER_INTERLEAVE_CONTACT_AND_FRICTION_CONSTRAINTS: each contact's friction rows are solved
  // right after its normal row instead of after all normal rows. Measured: converges worse
  // (never-sleeping stack 0.37 m at 7 iterations, bound 0.25); off.
  bool interleave_friction = false;
  // Patch friction (physics/contact_solver.h; sequential impulse only, ignored with kNNCG): per
  // contact manifold two tangent rows at the patch centre clamped together to the friction disk
  // mu * (sum of the manifold's normal impulses), plus one twist row about the normal (uniform-
  // pressure torque), instead of friction rows per contact point; tangent impulses are warm
  // started. Replaces
  // the per-point friction settings above for manifolds it handles (all but those with
  // rolling/spinning friction or friction anchors); interleave_friction is ignored. Rows per
  // 4-point box pair: 7 instead of 8 (one row per point) or 12 (two). Measured (full stir,
  // docs/benchmarks.md "Full stir, session 12"): 0.844x raw Bullet at 7 iterations against
  // 0.885x without, 0.740x with 4 iterations, one batch and a 5 mm margin.
  // History: with the rows solved one at a time a never-sleeping pile crept (the boxes rocked
  // with a growing amplitude: a 4 x 4 layer of touching boxes moved 2.1 mm in 5 s and 9.7 mm in
  // 20 s, the pile of ManifoldReuseTest 4 mm; session 13). The block solve holds the layer below
  // 0.001 mm for 20 s (Bullet's friction: 0.04 mm), the pile within ManifoldReuseTest's 2 mm, and
  // the never-sleeping ten-box stack to 3 mm at 4 iterations (docs/benchmarks.md, "Full stir,
  // session 14: a block solve for patch friction"). Still off by default: with it and 4
  // iterations as defaults the SDK's stack-and-grab examples failed (the stacked boxes reported
  // a collision exit and enter while settling; not traced); see that section.
  bool patch_friction = false;
  // CCD sweeps (Bullet's predictive contacts and motion clamping) test fast dynamic bodies
  // against static and kinematic bodies only (the walls a body could pass through), not against
  // other dynamic bodies (those collide through their discrete contacts). Cost saved: the
  // box-box part of the sweeps. Accuracy: a fast small body can pass through a thin *dynamic*
  // body in one step. Measured on the full stir: no saving within the noise, and 5 of 2,000
  // boxes escaped the container; off. Traced in session 14 (docs/benchmarks.md, "Full stir,
  // session 14: containment without sweeps"): 19 of 22 escapes in 30 s were boxes thrown out
  // over the walls (box-box impacts without predictive contacts), 3 were pushed through a wall.
  bool ccd_static_only = false;
  // A dynamic body's broadphase AABB (over its current and predicted pose) is grown by
  // aabb_margin (m; Bullet: gContactBreakingThreshold, 0.02). Box-box contacts exist only when
  // boxes overlap and other pairs produce points within ~2-4 mm (the shapes' breaking
  // thresholds), so a smaller margin means fewer broadphase pairs to test; too small and a pair
  // is found a step late. aabb_hysteresis (m, 0: off): the broadphase gets the AABB grown by
  // this much more, and is only updated when the body's AABB leaves it, so small motions cost
  // no sort; the price is more (looser) pairs for the narrowphase to reject. Measured (full
  // stir): 5 mm saves ~2 % of the step (the default since session 12); 10 mm and hysteresis of
  // 1-2 cm save nothing measurable.
  float aabb_margin = 0.005f;
  float aabb_hysteresis = 0.0f;
  // Manifolds and collision algorithms preallocated per world (Bullet's default: 4,096 each,
  // about 3.6 MB per world whether used or not; 256 is about 0.23 MB). Beyond the pool Bullet
  // allocates per new contact pair (malloc/free per pair that starts or stops touching), so a
  // busy pile pays a little per step: measured in docs/benchmarks.md ("Memory per user"),
  // `physics_cost_report --only new-defaults,pools-4096`. Values below 64 count as 64.
  int contact_pool_size = 256;
  // Contact points farther apart than this (m) get no solver constraint (Bullet's default:
  // unlimited, i.e. every manifold point within the breaking threshold is solved).
  float contact_processing_threshold = 1e18f;
  float contact_distance = 0.005f;    // a manifold point closer than this counts as touching (m)
  // Resting regions (physics/rest_manager.h): a dynamic body below both rest thresholds for
  // rest_time seconds is FROZEN, i.e. made temporarily static to Bullet (zero inverse mass,
  // CF_STATIC_OBJECT, ISLAND_SLEEPING, AABB no longer updated), so it splits from the moving
  // part's island and costs no solver rows, no narrowphase against other resting bodies and no
  // integration. Bullet's own island sleeping cannot do this for a pile stirred anywhere (one
  // island). It is UNFROZEN (mass and inertia restored bit-exactly, velocity zero) before a
  // step when a non-frozen dynamic body above the rest thresholds or a soft body overlaps its
  // AABB grown by rest_wake_margin, when a kinematic body's path this step comes that close,
  // after a step when a contact pushes it by more than rest_wake_delta_v (impulse / its mass),
  // and on any API call that touches it or its surroundings (SetTransform, SetVelocity, Grab,
  // a joint to it, adding/removing/teleporting an entity overlapping it). Never frozen:
  // grabbed bodies, bodies with joints, bodies touching soft bodies; nothing when `sleeping`
  // is false.
  // Accuracy: a frozen body ignores gravity and creep below the thresholds (at most
  // rest_linear_threshold * rest_time of drift is cut off, and its velocity is zeroed); a body
  // hit faster than the look-ahead margin covers (> ~(rest_wake_margin + 2 cm) per step) acts as
  // a static wall for that one step before the impulse rule wakes it. Measured against the
  // setting off in docs/benchmarks.md ("Rest resting regions") and physics/rest_manager_test.cc.
  // Cost when on: O(broadphase pairs) per step while many are frozen, O(frozen * log n) while
  // few are (a scene where almost nothing rests, e.g. the full stir), O(collision objects)
  // per moving kinematic body, O(manifolds) after the step; it pays wherever a share of the
  // bodies rests while others move.
  bool rest_freeze = true;
  float rest_linear_threshold = 0.1f;    // m/s (0.05 froze 47 % instead of 59 %)
  float rest_angular_threshold = 0.2f;   // rad/s (0.1 likewise)
  float rest_time = 0.5f;                // s below both thresholds before freezing
  float rest_wake_margin = 0.05f;        // m: look-ahead around a frozen body's AABB
  float rest_wake_delta_v = 0.33f;       // m/s: ~2 * g * dt, twice what resting weight pushes
  // Stability guard thresholds.
  float max_linear_speed = 200.0f;      // m/s
  float max_angular_speed = 1000.0f;    // rad/s
  float soft_max_node_speed = 100.0f;   // m/s
  float soft_max_extent_ratio = 4.0f;   // AABB diagonal vs. the diagonal when added
  int soft_soften_after_resets = 3;     // consecutive resets before kLST is clamped to 1
  // Soft bodies.
  int soft_iterations = 4;                // position solver iterations (Bullet piterations)
  float soft_max_link_stiffness = 1.0f;   // clamp for the derived kLST (see header comment)
  float soft_margin = 0.02f;              // collision margin of soft bodies (m)
  // Grab drive (velocity control towards the MoveToTransform target).
  float grab_gain = 1.0f;               // fraction of the pose error removed per step
  float grab_max_speed = 10.0f;         // m/s
  float grab_max_angular_speed = 20.0f; // rad/s
  // A released object leaves at its hand's velocity (and the angular velocity the hand turns
  // at), estimated from the hand's poses of the last `release_velocity_window_s` seconds with
  // the times they hold (RoomPhysics::Drive, physics/pose_history.h), not at the drive's last
  // step, which asks for 0 to ~2x the hand's speed depending on how poses fell between steps.
  // Longer windows average out more timing jitter but lag a hand that speeds up (they give the
  // mean velocity over the window). 0: keep the drive's last step (the old behaviour). Cost:
  // O(8) per release, ~300 bytes per driven entity.
  float release_velocity_window_s = 0.1f;
  // Validation limits.
  size_t max_colliders = 64;
  size_t max_mesh_vertices = 65536;
  size_t max_mesh_triangles = 131072;
  size_t max_soft_nodes = 4096;
  size_t max_soft_springs = 65536;
  size_t max_joints = 16;
  size_t max_pending_events = 65536;  // events beyond this (undrained) are dropped and counted
};

// Why a container was rejected.
enum class InvalidReason : uint8_t {
  kNone = 0,
  kZeroId,             // entity_id 0 is reserved
  kNaN,                // a non-finite number anywhere
  kNegativeMass,       // rigid-body or particle mass < 0
  kOutOfRange,         // sizes <= 0, friction < 0, restitution/damping outside [0, 1],
                       // zero-length quaternion/axis, position outside the world bounds;
                       // a scaled collider size outside [0.1 mm, 2 * world_half_extent], a
                       // scaled offset or vertex beyond 2 * world_half_extent; a dynamic
                       // mass or a non-zero particle mass outside [1e-6, 1e9] kg
  kDegenerateMesh,     // hull without volume, mesh without (non-degenerate) triangles, bad indices
  kTooManyNodes,       // soft-body particles/springs or mesh size over the configured limits
  kTooManyColliders,   // over max_colliders or max_joints
  kUnknownShape,       // collider shape or joint kind not in the schema
  kDuplicateId,        // entity_id already in the world
  kUnknownParent,      // parent_id not in the world
  kUnknownJointTarget, // connected_entity not in the world or without a rigid body
  kBadJoint,           // joint on an entity without a rigid body
  kBadSoftBody,        // masses/particles count mismatch, spring index out of range
  kSoftBodiesDisabled, // PhysicsConfig::soft_body_world is false
};
std::string_view InvalidReasonName(InvalidReason reason);

enum class PhysicsEventType : uint8_t {
  kCollisionEnter,  // entity_a < entity_b
  kCollisionExit,
  kTriggerEnter,    // entity_a: the trigger's entity, entity_b: the body entering it
  kTriggerExit,
  kGuardReset,      // entity_a: the entity restored by the stability guard, entity_b: 0
};

enum class GuardCause : uint8_t {
  kNone,
  kNonFinite,          // NaN/inf transform or velocity
  kRunawaySpeed,       // over max_linear_speed / max_angular_speed
  kOutOfBounds,        // outside the world bounds (the body is restored and put to sleep)
  kSoftBodyExploded,   // node speed or extent growth over the soft thresholds
};

struct PhysicsEvent {
  PhysicsEventType type = PhysicsEventType::kCollisionEnter;
  GuardCause cause = GuardCause::kNone;  // kGuardReset only
  uint32_t entity_a = 0;
  uint32_t entity_b = 0;
  uint64_t step = 0;  // the step (1-based count of Step() calls) that produced the event
};

struct PhysicsCounters {
  uint64_t steps = 0;
  size_t entities = 0;        // all entities, including transform-only nodes
  size_t bodies = 0;          // Bullet rigid bodies (static, kinematic and dynamic)
  size_t dynamic_bodies = 0;
  size_t sleeping_bodies = 0; // dynamic bodies not simulated in the last step (incl. frozen)
  size_t frozen_bodies = 0;   // of those, frozen by PhysicsConfig::rest_freeze
  uint64_t rest_wakes = 0;    // frozen bodies woken again (all causes)
  size_t soft_bodies = 0;
  size_t joints = 0;
  uint64_t guard_resets = 0;
  uint64_t soft_softened = 0;       // soft bodies whose kLST the guard clamped
  uint64_t rejected_containers = 0;
  uint64_t events_dropped = 0;
};

class PhysicsWorld {
 public:
  explicit PhysicsWorld(const PhysicsConfig& config = {});
  ~PhysicsWorld();
  PhysicsWorld(const PhysicsWorld&) = delete;
  PhysicsWorld& operator=(const PhysicsWorld&) = delete;

  const PhysicsConfig& config() const { return config_; }

  // Checks a container against this world (ids, parents, joint targets, limits) without
  // changing anything. O(size of the container).
  InvalidReason Validate(const schema::Container& c) const;

  // Builds the entity. On failure nothing changes; `reason` (optional) says why.
  // Errors: kAlreadyExists (duplicate id), kTooLarge (limits), kInvalidArgument (the rest).
  // Cost: O(container size); triangle meshes build a BVH (O(n log n)).
  Status AddEntity(const schema::Container& c, InvalidReason* reason = nullptr);

  // Removes the entity, its joints (also those of other entities pointing at it), and its grab.
  // Children stay where they are and become roots. Pairs it was in report Exit on the next step.
  Status RemoveEntity(uint32_t id);
  bool HasEntity(uint32_t id) const;

  // Kinematic entities: reach the pose at the end of the next Step() (Bullet derives their
  // velocity from the displacement, so they push dynamic bodies). Grabbed dynamic entities: sets
  // the drive target. Transform-only and static entities: teleport. Dynamic entities that are not
  // grabbed: kInvalidArgument (use SetTransform to teleport). `rot` is normalised (a zero-length
  // one is identity). A non-finite pose or a position outside the world bounds:
  // kInvalidArgument, nothing changes.
  Status MoveToTransform(uint32_t id, const Vec3f& pos, const Quatf& rot);
  // Teleports any entity (failover restore); keeps velocities of dynamic bodies. Errors as
  // MoveToTransform's.
  Status SetTransform(uint32_t id, const Vec3f& pos, const Quatf& rot);

  // Starts driving a dynamic entity (with the Interactable flag) by velocity control towards
  // the MoveToTransform target, so it collides instead of passing through walls. Gravity is
  // off while grabbed. `hand_entity` (0: none) is recorded; removing the hand releases.
  // Errors: kNotFound, kInvalidArgument (not dynamic), kPermissionDenied (not Interactable).
  Status Grab(uint32_t entity, uint32_t hand_entity);
  Status Release(uint32_t entity);  // keeps the current velocity (throwing works)
  bool IsGrabbed(uint32_t entity) const;

  Status SetVelocity(uint32_t id, const Vec3f& linear, const Vec3f& angular);  // wakes the body
  Status GetVelocity(uint32_t id, Vec3f* linear, Vec3f* angular) const;
  Status GetState(uint32_t id, EntityState* state) const;  // current transform
  // Node positions of a soft body (room frame); `out` is resized. kNotFound if not soft.
  Status GetSoftBodyNodes(uint32_t id, std::vector<Vec3f>* out) const;
  // Failover restore of a deformed soft body: nodes [first, first + nodes.size()) take these
  // positions (room frame, m) at rest (zero velocity and force); the rest lengths stay those of
  // the spawn shape, so the body keeps the deformation it had and relaxes from there as it would
  // have. The stability guard's last good state becomes these positions. Errors: kNotFound (not
  // a soft body), kInvalidArgument (first + size above the body's node count, or a non-finite
  // position or one outside the world bounds); nothing changes on error. O(nodes given).
  Status SetSoftBodyNodes(uint32_t id, uint32_t first, std::span<const Vec3f> nodes);

  // Advances exactly one fixed step of config().fixed_dt: applies pending kinematic moves and
  // grab drives, steps Bullet, runs the stability guard, diffs contact pairs into events.
  void Step();
  // Accumulates wall time and runs up to max_substeps fixed steps; returns the number run.
  int Advance(double elapsed_seconds);

  // Replaces `moved` by the entities whose transform changed since the last call: active
  // (non-sleeping) bodies that moved, moved kinematic/teleported entities, transform-only
  // descendants of moved entities, and active soft bodies (position: AABB centre, identity
  // rotation). Sleeping bodies are never visited. Order: order of activity (deterministic for
  // identical input).
  void CollectStates(std::vector<EntityState>* moved);

  // Appends the events since the last call (in step order; within a step sorted by pair) to
  // `out` and forgets them.
  void DrainEvents(std::vector<PhysicsEvent>* out);

  PhysicsCounters counters() const;

  // All entity ids, sorted ascending. O(n log n), allocates; for hashing and tests.
  void EntityIds(std::vector<uint32_t>* ids) const;

  // Escape hatches for tests and benchmarks; the pointers are owned by the world and valid until
  // the entity is removed. nullptr if the entity has no such object.
  btRigidBody* RigidBodyForTesting(uint32_t id) const;
  btSoftBody* SoftBodyForTesting(uint32_t id) const;
  btDiscreteDynamicsWorld* BulletWorldForTesting() const { return world_.get(); }

  struct Entity;  // defined in physics_world_internal.h

 private:
  struct PairKey {
    uint32_t a = 0;
    uint32_t b = 0;
    uint32_t trigger = 0;
    auto operator<=>(const PairKey&) const = default;
  };
  struct JointRecord;

  // physics_world.cc
  Entity* Find(uint32_t id) const;
  void MarkDirty(Entity* e);
  void PushEvent(const PhysicsEvent& ev);
  void ApplyCommands();
  void RemoveJointsOf(uint32_t id);
  void ReportTree(Entity* e, std::vector<EntityState>* moved);
  // The configured broadphase; kAxisSweep with `handles` proxies.
  std::unique_ptr<btBroadphaseInterface> NewBroadphase(int handles);
  // kAxisSweep: grows (doubles) the sweep so that `more` collision objects fit. O(objects).
  void ReserveBroadphase(int more);
  static constexpr int kInitialSweepHandles = 1024;
  // AddEntity's steps after validation (body_builder.cc).
  std::unique_ptr<Entity> NewEntity(const schema::Container& c);
  void AddSoftBody(Entity* e, const schema::Container& c);
  void AddRigidParts(Entity* e, const schema::Container& c);
  void AddRigidBody(Entity* e, const schema::Container& c, const internal::BodyShapes& shapes);
  void AddTrigger(Entity* e, btCollisionShape* shape);
  void AddJoints(Entity* e, const schema::Container& c);
  // stability_guard.cc
  void RunGuard();
  void RunSoftGuard(Entity* e);
  void ResetRigid(Entity* e, GuardCause cause);
  // contact_tracker.cc
  void DiffContacts();

  PhysicsConfig config_;
  std::unique_ptr<btCollisionConfiguration> collision_config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btBroadphaseInterface> broadphase_;
  std::unique_ptr<btConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  btSoftBodyWorldInfo* soft_info_ = nullptr;  // owned by world_ (null without soft bodies)
  std::unique_ptr<btRigidBody> fixed_body_;   // joint partner for "anchored to the world"
  std::unique_ptr<RestManager> rest_;         // freezing of resting bodies (rest_freeze)

  std::unordered_map<uint32_t, std::unique_ptr<Entity>> entities_;
  std::vector<std::unique_ptr<JointRecord>> joints_;
  std::vector<Entity*> stepped_;          // dynamic bodies Bullet synchronised this step
  std::vector<Entity*> dirty_;            // moved since the last CollectStates
  std::vector<Entity*> pending_moves_;    // kinematic targets to apply before the next step
  std::vector<Entity*> moving_;           // kinematic entities moving during this step
  std::vector<Entity*> grabbed_;
  std::vector<Entity*> trigger_followers_;  // trigger objects following a moving body
  std::vector<Entity*> soft_entities_;
  std::vector<PairKey> pairs_;            // touching pairs after the last step (sorted)
  std::vector<PairKey> new_pairs_;        // scratch
  std::vector<PhysicsEvent> events_;
  std::vector<PhysicsEvent> step_events_; // scratch: this step's contact events
  double accumulator_ = 0.0;
  size_t dynamic_bodies_ = 0;
  size_t bodies_ = 0;
  size_t last_active_ = 0;
  int sweep_handles_ = 0;          // kAxisSweep: capacity of the sweep (0: btDbvtBroadphase)
  float deactivation_scale_ = 0;  // extra below-threshold seconds per second (deactivation_time)
  PhysicsCounters stats_;

  friend class EntityMotionState;
};

}  // namespace edgephys::physics
