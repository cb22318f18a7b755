// RoomPhysics: PhyS for one room, embedded in the relay — the room's Bullet world
// (physics/physics_world.h) plus what the relay needs around it: which entities PhyS
// simulates and which it mirrors, trigger hovering for grabs, holding grabbed objects in the
// hand, and stepping at the fixed rate.
//
// Roles (RoleOf):
//  * kSimulated: the entity carries the Offloaded flag and a dynamic rigid body or a soft
//    body. PhyS owns its state; the relay replicates what PhyS produces.
//  * kMirrored: any other entity with colliders or a rigid body (a local-physics user's
//    hands, head, held objects; an offloaded client's kinematic hands). Added as a kinematic
//    body and driven by its owner's state updates (Drive), so it pushes simulated objects.
//  * kNone: no physics; PhyS never sees it.
//
// Thread-safety: none; owned by the room's thread. Cost: Advance() is the physics step
// (Bullet's cost) plus O(moved entities + events); other calls are O(1) amortised.
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "edgephys/schema/container_generated.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/pose_history.h"
#include "protocol/state_codec.h"

namespace edgephys {

enum class PhysicsRole : uint8_t { kNone = 0, kMirrored, kSimulated };

class RoomPhysics {
 public:
  RoomPhysics(const physics::PhysicsConfig& config, double now);

  static PhysicsRole RoleOf(const schema::Container& c);

  // Adds an entity in its role (kMirrored entities are rebuilt as kinematic bodies). On
  // failure (invalid components) returns kInvalidArgument and explains in `*detail`.
  Status Add(const schema::Container& c, PhysicsRole role);
  void Remove(uint32_t id);
  bool Has(uint32_t id) const { return roles_.count(id) != 0; }

  // An owner moved a mirrored entity: the kinematic body follows, and so does whatever that
  // entity holds. `time` is when the pose holds, on the clock of Advance's `now` (the relay's:
  // when the pose arrived); the poses' times give the velocity a released object leaves with
  // (Release). The last pose before each Advance is the one kept (as the async link coalesces
  // drives). A pose whose time is older than the newest kept is not used for the velocity.
  void Drive(uint32_t id, const EntityState& state, double time);

  // Attaches simulated, Interactable `entity` to `hand` at their current relative pose.
  // kFailedPrecondition-like errors (kPermissionDenied) with `*detail` unless the hand's
  // trigger hovers the entity and nobody else holds it.
  // `require_hover` false re-attaches without the trigger check (failover of a held object).
  Status Grab(uint32_t entity, uint32_t hand, bool require_hover = true);
  // Lets go of `entity`. With PhysicsConfig::release_velocity_window_s > 0 and enough recent
  // hand poses (physics/pose_history.h), the entity leaves at the hand's velocity at its place
  // (v_hand + w_hand x (p - p_hand), and the hand's angular velocity, capped at the grab drive's
  // limits); otherwise with the drive's last velocity. kNotFound if not held.
  Status Release(uint32_t entity);
  // The hand holding `entity`, 0 if none.
  uint32_t HolderOf(uint32_t entity) const;

  // Restores a simulated entity's pose and velocities (failover onto a fresh world).
  void Restore(uint32_t id, const EntityState& state, const Vec3f& linear, const Vec3f& angular);
  // Restores particles [first, first + nodes.size()) of a soft body to their deformed positions
  // (failover onto a fresh world; PhysicsWorld::SetSoftBodyNodes). Errors as that function's.
  Status RestoreSoftBody(uint32_t id, uint32_t first, std::span<const Vec3f> nodes) {
    return world_.SetSoftBodyNodes(id, first, nodes);
  }

  struct MovedBody {
    EntityState state;
    Vec3f linear;   // m/s
    Vec3f angular;  // rad/s
  };
  struct SoftNodes {           // particles [first, first + nodes.size()) of `total`
    uint32_t id = 0;
    uint32_t total = 0;
    uint32_t first = 0;
    std::vector<Vec3f> nodes;
  };
  struct GrabResult {
    uint32_t entity = 0;
    uint32_t hand = 0;
    bool ok = false;
    std::string detail;
  };
  struct StepOutput {
    std::vector<MovedBody> moved;                 // simulated entities that moved
    std::vector<SoftNodes> soft;                  // simulated soft bodies that moved
    std::vector<physics::PhysicsEvent> events;    // in step order
    std::vector<GrabResult> grabs;                // answers to RequestGrab, in request order
    int steps = 0;
    double step_seconds = 0;                      // wall time of those steps
    // When `moved` holds (the end of the last step), on the clock of the caller's `now` (the
    // relay's); < 0 when unknown (RoomPhysics itself, remote workers): the caller's `now`.
    double state_time = -1;
    void Clear() {
      moved.clear();
      soft.clear();
      events.clear();
      grabs.clear();
      steps = 0;
      step_seconds = 0;
      state_time = -1;
    }
  };
  // Runs the fixed steps due by `now`. `out` is cleared first.
  void Advance(double now, StepOutput* out);
  // Grab() whose answer is delivered in the next Advance() output (the interface the relay
  // uses for embedded and remote PhyS alike).
  void RequestGrab(uint32_t entity, uint32_t hand, bool require_hover = true);

  // Poses and velocities of every simulated rigid entity (periodic full refreshes).
  void SnapshotSimulated(std::vector<MovedBody>* out) const;

  Status GetSoftBodyNodes(uint32_t id, std::vector<Vec3f>* nodes) const {
    return world_.GetSoftBodyNodes(id, nodes);
  }
  Status GetVelocity(uint32_t id, Vec3f* linear, Vec3f* angular) const {
    return world_.GetVelocity(id, linear, angular);
  }
  physics::PhysicsCounters counters() const { return world_.counters(); }

 private:
  struct Hold {
    uint32_t hand = 0;
    Vec3f offset_position;  // the entity's pose in the hand's frame
    Quatf offset_rotation;
  };
  physics::PhysicsWorld world_;
  double time_;
  std::unordered_map<uint32_t, PhysicsRole> roles_;
  std::set<uint32_t> soft_;  // entities with a soft body
  std::set<std::pair<uint32_t, uint32_t>> hovering_;  // (trigger entity, entity inside)
  std::unordered_map<uint32_t, Hold> holds_;          // by held entity
  // Poses of driven (mirrored) entities: the last Drive since the previous Advance, and one
  // pose per Advance before it (~350 bytes per driven entity).
  struct DrivenPoses {
    bool pending = false;
    double time = 0;
    EntityState state;
    physics::PoseHistory history;
  };
  std::unordered_map<uint32_t, DrivenPoses> driven_;
  std::vector<uint32_t> pending_driven_;  // ids Drive()n since the last Advance
  void CommitDrivenPoses();  // O(entities driven since the last Advance)
  std::vector<EntityState> scratch_states_;
  std::vector<GrabResult> pending_grabs_;
};

}  // namespace edgephys
