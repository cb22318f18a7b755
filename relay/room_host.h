// RoomHost: one room's behaviour. It owns the Room (the data) and applies the room's rules:
// membership (join, leave, late join: the state a joiner is sent), entity authority (who may
// spawn, despawn, move and grab what), PhyS output and failover, and fan-out (reliable
// broadcasts and the replication tick's receivers). It reaches members only through
// MemberLink and PhyS only through PhysicsLink/PhysicsPlacement, so its rules are tested
// without sockets (relay/room_host_test.cc).
//
// Requests a rule refuses are answered on the requester's link with Error{reason} and counted
// (MemberLink::SendError); untrusted state updates that fail a check are dropped and counted
// (MemberLink::DropUpdate), never asserted on.
//
// Thread-safety: one thread (the relay's) for every method; during a replication tick the
// relay may run MemberLink::Replicate for the receivers BeginTick returned in parallel, which
// only read the room's entities. Cost: each method is O(members) for its broadcasts plus the
// work named on it.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "relay/join_stream.h"
#include "relay/member_link.h"
#include "relay/property_table.h"
#include "relay/rate_limit.h"
#include "relay/relay_config.h"
#include "relay/relay_counters.h"
#include "relay/room.h"
#include "relay/worker_directory.h"

namespace edgephys {

// What a room needs from the relay that hosts it. Not owned; all must outlive the room.
struct RoomHostEnv {
  const AbuseLimits* limits = nullptr;
  RelayCounters* counters = nullptr;
  PhysicsPlacement* placement = nullptr;  // where the room's PhyS is created
};

class RoomHost {
 public:
  RoomHost(std::string name, const RoomConfig& config, const RoomHostEnv& env, double now);
  RoomHost(const RoomHost&) = delete;
  RoomHost& operator=(const RoomHost&) = delete;

  const Room& room() const { return room_; }
  const std::string& name() const { return room_.name(); }
  // The state format this room's Joined announces and its replication sends (docs/protocol.md
  // §5): 9 (shared delta) by default, 2/12/13/14 when a policy of the format-2 family or
  // --no-shared-encoding asks for it, the emulation formats for the baselines. O(1).
  uint8_t state_format() const;
  // Members or entities: an operator may not replace the room.
  bool in_use() const { return !room_.empty() || !room_.entities().empty(); }
  // Empty for at least the room's idle TTL.
  bool IdleExpired(double now) const;
  // The link of a member, null if `player_id` is not in the room.
  MemberLink* FindMember(uint32_t player_id) const;

  // --- Membership -------------------------------------------------------------------------
  // Admits `link`'s player: queues Joined (its slot's entity id block, the state format and
  // quantisation) and RoomState on its reliable channel, starts its replication, starts its
  // JoinStream (one Spawn per existing entity, paced by its reliable queue: sent here as far as
  // it fits, then by BeginTick until done), and tells the other members PlayerJoined. False (Error{RoomFull} sent)
  // when the room is full. The player must not be a member already (the relay replaces an
  // older session of the same player first). O(entities + members).
  bool Join(MemberLink& link, double now);
  // Removes the player if `link` is its current link (else nothing). Its non-persistent
  // entities are despawned for everyone (Despawn each, and every remaining member forgets
  // them); persistent ones pass to the room (owner 0). Then PlayerLeft. O(entities x members).
  void Leave(MemberLink& link, double now);

  // --- Requests of a member (refused ones: Error{reason} on `link`) ------------------------
  // A spawn: `message` is the whole verified ControlMessage{Spawn}. Checks size, rate,
  // permission, id block, owner, duplicate id, the transform (finite, unit rotation, scale in
  // [1e-4, 1e4]), the parent (an existing entity) and the budgets (relay/room_budget.h:
  // Error{EntityLimit} for the player's entity limit, Error{OverBudget} naming any other, and
  // counted by budget); physics components go to PhyS (created on first use). Broadcast to the others (to all,
  // with owner 0, when PhyS simulates it).
  void Spawn(MemberLink& link, std::span<const uint8_t> message, const schema::Spawn& spawn,
             double now);
  // Its owner (or the creator of a PhyS-owned entity) removes it for everyone.
  void Despawn(MemberLink& link, uint32_t entity_id);
  // A grab of a PhyS-simulated entity by the member's hand; answered after a physics step
  // (Grabbed to all, or Error{GrabRefused} to the requester).
  void Grab(MemberLink& link, uint32_t entity_id, uint32_t hand_id);
  // A grab with the hand's pose now (relay/room_grab.cc): refused with GrabRefused (and counted
  // in grab_pose_stats().refused) when the pose names another entity, is not finite or not a
  // unit rotation, or lies more than kMaxGrabPoseOffsetM from the hand's last accepted state;
  // else applied as the hand's state (as ApplyStates would) and the grab is asked of PhyS once
  // it has stepped twice with it (the hover is judged there), answered as Grab's.
  static constexpr float kMaxGrabPoseOffsetM = 0.5f;
  void GrabAt(MemberLink& link, uint32_t entity_id, uint32_t hand_id, const schema::Pose& pose,
              double now);
  struct GrabPoseStats {
    uint64_t applied = 0;  // grabs whose pose was applied
    uint64_t refused = 0;  // refused for their pose
  };
  const GrabPoseStats& grab_pose_stats() const { return grab_pose_stats_; }
  // Releases what the member's hand holds; Released to all.
  void Release(MemberLink& link, uint32_t entity_id, double now);
  // An application message from the member (docs/protocol.md, "Application messages"),
  // forwarded on the reliable channel, with the sender's player id, to the members `message`
  // addresses (each once, in the order this member sent them). Refused (Error on `link`,
  // counted in requests_rejected and in message_stats().refused) without the join token's
  // kPermissionMessage (NotPermitted), over RoomBudgets::max_message_bytes (OverBudget), over
  // the per-player or the room's message or byte rate (RateLimited), for a Player target not
  // in the room (UnknownPlayer) or an unknown target (InvalidMessage). O(members).
  void Message(MemberLink& link, const schema::AppMessage& message, double now);
  // An unreliable application message (`payload`: the whole format-15 unreliable payload,
  // protocol/app_message_codec.h): the same rules, permission and budgets as Message (one
  // budget for both kinds), forwarded as one datagram to each addressed member that is ready
  // for states (MemberLink::SendUnreliable) with the sender's id and the next of the sender's
  // unreliable sequence numbers (per player identity). A payload shorter than the header is
  // dropped as malformed (DropPayload) and refused. O(members).
  void MessageUnreliable(MemberLink& link, std::span<const uint8_t> payload, double now);
  struct MessageStats {
    uint64_t forwarded = 0;  // messages accepted (both kinds)
    uint64_t delivered = 0;  // copies queued or sent to members
    uint64_t refused = 0;    // messages refused (any reason, both kinds)
    uint64_t unreliable = 0;  // of `forwarded`, unreliable ones
  };
  const MessageStats& message_stats() const { return message_stats_; }

  // A property write from the member (docs/protocol.md, "Properties"; relay/room_properties.cc).
  // Accepted: stored (version 1 on creation, +1 after) and PropertyChanged sent to every member,
  // the writer included, in the order of acceptance. A compare-and-set whose expected version
  // is not the property's (0: it must not exist) is answered with PropertyConflict carrying
  // the current value and version to the writer only, and counted in conflicts. Refused (Error
  // on `link`, counted in requests_rejected and property_stats().refused): without the join
  // token's kPermissionProperty (NotPermitted); over the player's write rate (RateLimited); a
  // bad key, an unknown type tag or authority, a NaN/infinite double/vec3/quat, a missing value
  // (InvalidMessage); an entity the room does not hold (UnknownEntity); a property under Owner
  // authority written by another than its owner (the entity's owner, or the room property's
  // creator), or created Owner-only on another's entity (NotOwner); the authority is fixed
  // when the property is created; a string/bytes value over
  // RoomBudgets::max_property_value_bytes, a new property over max_properties, or bytes over
  // max_property_bytes (OverBudget, detail "over budget: <budget>", also counted by budget).
  // O(log properties + members).
  void SetProperty(MemberLink& link, const schema::PropertySet& set, double now);
  struct PropertyStats {
    uint64_t accepted = 0;   // writes stored and broadcast
    uint64_t conflicts = 0;  // compare-and-set writes that lost
    uint64_t refused = 0;    // writes refused (any reason)
  };
  const PropertyStats& property_stats() const { return property_stats_; }
  const PropertyTable& properties() const { return properties_; }
  // Cluster failover: properties as a snapshot held them. A room property is taken as it is; an
  // entity property only when the room holds its entity (Restore first), else it is skipped.
  // Invalid keys and values are skipped too. Returns how many were skipped. Call before members
  // join. O(properties).
  size_t RestoreProperties(std::vector<std::pair<PropertyTable::Key, StoredProperty>> properties);

  // An ownership request from the member (docs/protocol.md, "Ownership";
  // relay/room_ownership.cc). Request: granted at once (the sender becomes the owner) when the
  // room owns the entity (owner 0) or its owner allows takeover. HandOver: the owner gives it to
  // another member; Release: the owner gives it to the room; SetTakeover: the owner allows or
  // forbids takeover (kept across changes of owner). Each change of owner bumps the entity's
  // authority_seq, rewrites the owner in its stored spawn (late joiners) and sends
  // OwnershipChanged to every member; from then on the previous owner's states are dropped and
  // counted (ApplyStates). A Request by the current owner is answered with OwnershipChanged to
  // it alone. Physics switches without a despawn (SwitchPhysics): a Release of a body its owner
  // simulates locally (mirrored, dynamic rigid body) hands it to PhyS at its pose and the
  // request's velocities; a Request of a PhyS-simulated body (not held, not soft) makes it the
  // requester's, kinematic in PhyS, and the OwnershipChanged carries PhyS's pose and velocities. Refused (Error on `link`, counted in requests_rejected and
  // ownership_stats().refused): over the player's request rate (RateLimited); an unknown action
  // (InvalidMessage); a join token without kPermissionSpawn, the sender's or a HandOver
  // receiver's (NotPermitted); an entity the room does not hold (UnknownEntity); a Request of
  // an entity PhyS simulates that a hand holds or that is a soft body, or whose owner forbids
  // takeover (TakeoverRefused); a Release with velocities not finite or over 1,000
  // (InvalidMessage); HandOver,
  // Release or SetTakeover by another than the owner (NotOwner); a HandOver to a player not
  // in the room (UnknownPlayer) or to the owner itself (InvalidMessage). O(members).
  void Ownership(MemberLink& link, const schema::OwnershipRequest& request, double now);
  struct OwnershipStats {
    uint64_t changes = 0;  // changes of owner
    uint64_t refused = 0;  // requests refused (any reason)
    uint64_t stale = 0;    // states of a previous owner dropped
    // A leaver's entities (LeaveChoiceOf): given to the room at rest, or offloaded to PhyS.
    uint64_t left_to_room = 0;
    uint64_t left_to_phys = 0;
  };
  const OwnershipStats& ownership_stats() const { return ownership_stats_; }

  // An unreliable state payload from the member: each state is applied if the member owns the
  // entity and it is valid (early states of its own unspawned entities are held, bounded).
  // States of the entity's owner before its latest change are also counted as stale
  // (ownership_stats().stale, RelayCounters::stale_owner_states). O(states).
  void ApplyStates(MemberLink& link, std::span<const uint8_t> payload, double now);

  // --- PhyS -------------------------------------------------------------------------------
  // The room's physics link, after failing it over if unhealthy; null without physics.
  PhysicsLink* PreparePhysics(double now);
  // Folds a step's output into the entities and broadcasts its events and grab answers.
  void ApplyPhysics(const PhysicsLink::StepOutput& output, double now);
  // Rebuilds PhyS on a new link (another worker than the failed one, or embedded) from the
  // containers, states and velocities the room holds; grabs are re-established.
  void FailOver(double now);
  // Connection id of the worker simulating the room, 0 if embedded or none.
  uint32_t physics_worker() const;

  // --- Cluster failover (relay/cluster_hook.h) ---------------------------------------------
  // Restores what a relay of the cluster saved for this room: slot reservations (players get
  // their entity id blocks back when they rejoin) and entities. Entities already in the room
  // are kept; a restored entity whose stored spawn is not a verifiable ControlMessage{Spawn}
  // for its id is skipped and counted in the return value. PhyS is rebuilt (FailOver) when any
  // entity has physics. Call before members join (members present are not sent the restored
  // entities). O(entities).
  size_t Restore(std::vector<Entity> entities, const std::map<uint32_t, uint32_t>& slots,
                 double now);

  // --- Fan-out ----------------------------------------------------------------------------
  bool TickDue(double now) const { return now >= room_.next_tick(); }
  // Starts a replication tick: quantises changed entities once for all receivers, schedules
  // the next tick and appends the members ready for states to `receivers`, who are then
  // replicated (MemberLink::Replicate) over room().entities().
  void BeginTick(double now, std::vector<MemberLink*>* receivers);
  // Queues `message` on every member's reliable channel but `except_player`'s (0: none).
  void BroadcastReliable(std::span<const uint8_t> message, uint32_t except_player);

 private:
  // Queues `message` for one member (after its join stream's state if it is still joining).
  void SendToMember(uint32_t player_id, const Member& member, std::span<const uint8_t> message);
  void BroadcastPhysicsEvent(schema::PhysicsEventKind kind, uint32_t a, uint32_t b, double now);
  void BroadcastDespawn(uint32_t entity_id, uint32_t except_player);
  void SendJoinState(MemberLink& link, uint32_t slot);
  // Queues PropertyChanged for every property the room holds to a joining member (after its
  // join stream's spawns).
  void SendJoinProperties(uint32_t player_id);
  // Queues OwnershipChanged to a joining member for every entity whose owner changed or that
  // allows takeover (after its join stream's spawns).
  void SendJoinOwnership(uint32_t player_id);
  // Before `leaver` leaves: each entity it owns goes where its LeaveChoiceOf says. Stay: the
  // room's at rest; PhyS: offloaded from its pose and the velocities its owner's states implied
  // (TrackOwnerMotion) when it is a dynamic body the leaver simulated, else Stay; Despawn: left
  // for Room::RemoveMember. Ownership changes are told to everyone but the leaver.
  void HandOffLeaversEntities(uint32_t leaver, double now);
  // Makes `owner` (0: the room) the owner of `e`: bumps its authority_seq, records the former
  // owner, rewrites its stored spawn and tells every member.
  // `except_player` (0: none) is not told (a leaving owner). With `motion`, the message carries
  // the entity's velocities (a switch between local physics and PhyS).
  void ChangeOwner(Entity& e, uint32_t owner, uint32_t except_player = 0, bool motion = false);
  // Rebuilds `e` in PhyS in `role` at its pose without a despawn: kSimulated (offload: PhyS
  // simulates it from `linear`/`angular`, m/s and rad/s) or kMirrored (reclaim: kinematic,
  // driven by its new owner). Records the velocities in the entity. False (nothing changed)
  // without PhyS, in that role already, or when PhyS refuses the body.
  bool SwitchPhysics(Entity& e, PhysicsRole role, const Vec3f& linear, const Vec3f& angular,
                     double now);
  // Sends what fits of the join streams (all members, or `only`); drops finished ones.
  void PumpJoinStreams(uint32_t only = 0);

  Room room_;
  RoomHostEnv env_;
  std::map<uint32_t, JoinStream> join_streams_;  // by player id, while a join streams
  StateBatch batch_;  // ApplyStates' decode buffer, reused
  // Message rates: per player identity (kept after a leave, so a rejoin does not refill them;
  // one entry per player that ever sent) and for the room.
  struct MessageRates {
    TokenBucket count, bytes;
    uint32_t unreliable_sequence = 0;  // the last unreliable message's number
  };
  // Message/MessageUnreliable's checks in the order docs/protocol.md lists them; false when
  // refused (Error on `link`, counted). `*to`: the addressed member with kPlayer.
  bool AdmitMessage(MemberLink& link, uint8_t target, uint32_t to_player, size_t size,
                    const Member** to, MessageRates** rates, double now);
  std::unordered_map<uint32_t, MessageRates> message_rates_;
  MessageRates room_message_rates_;
  bool message_rates_ready_ = false;
  MessageStats message_stats_;
  PropertyTable properties_;
  PropertyStats property_stats_;
  std::unordered_map<uint32_t, TokenBucket> property_rates_;  // per player identity
  OwnershipStats ownership_stats_;
  // Grabs waiting for PhyS to step with their hand's pose (GrabAt): steps still to wait.
  struct PosedGrab {
    uint32_t entity = 0, hand = 0;
    int steps_left = 2;
  };
  std::vector<PosedGrab> posed_grabs_;
  GrabPoseStats grab_pose_stats_;
  void IssuePosedGrabs(int steps);
  // The checks Grab and GrabAt share (relay/room_grab.cc): both entities exist, the hand is the
  // sender's, PhyS simulates the target. Returns the target, or nullptr after sending the Error.
  Entity* GrabTarget(MemberLink& link, uint32_t entity_id, uint32_t hand_id);
  std::unordered_map<uint32_t, TokenBucket> ownership_rates_;  // per player identity
};

}  // namespace edgephys
