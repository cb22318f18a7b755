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

#include "physics_backend/physics_settings.h"
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
                       // mass or a non-zero particle mass outside [1e-6, 1e9] kg; an initial
                       // velocity over max_linear_speed / max_angular_speed
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
