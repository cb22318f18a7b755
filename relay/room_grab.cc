// RoomHost::GrabAt (relay/room_host.h): a grab that carries the hand's pose now, so that it is
// judged against where the hand is, not against its last state to reach the relay; and the
// checks it shares with Grab (GrabTarget).
#include <cmath>

#include "relay/room_host.h"

namespace edgephys {

Entity* RoomHost::GrabTarget(MemberLink& link, uint32_t entity_id, uint32_t hand_id) {
  using schema::RejectReason;
  Entity* hand = room_.FindEntity(hand_id);
  Entity* e = room_.FindEntity(entity_id);
  if (hand == nullptr || e == nullptr) {
    link.SendError(RejectReason::UnknownEntity, e ? hand_id : entity_id, "no such entity");
    return nullptr;
  }
  if (hand->owner != link.player_id()) {
    link.SendError(RejectReason::NotOwner, hand_id, "not your hand");
    return nullptr;
  }
  if (room_.physics() == nullptr || e->physics != PhysicsRole::kSimulated) {
    link.SendError(RejectReason::GrabRefused, entity_id, "not simulated by PhyS");
    return nullptr;
  }
  return e;
}

void RoomHost::GrabAt(MemberLink& link, uint32_t entity_id, uint32_t hand_id,
                      const schema::Pose& pose, double now) {
  using schema::RejectReason;
  Entity* e = GrabTarget(link, entity_id, hand_id);
  if (e == nullptr) return;
  Entity* hand = room_.FindEntity(hand_id);
  const auto refuse = [&](const char* detail) {
    ++grab_pose_stats_.refused;
    link.SendError(RejectReason::GrabRefused, entity_id, detail);
  };
  if (pose.entity_id() != hand_id) return refuse("the hand pose names another entity");
  EntityState st;
  st.entity_id = hand_id;
  st.position = {pose.position().x(), pose.position().y(), pose.position().z()};
  st.rotation = {pose.rotation().x(), pose.rotation().y(), pose.rotation().z(),
                 pose.rotation().w()};
  if (!IsValidState(st)) return refuse("the hand pose is not finite or not a unit rotation");
  const float dx = st.position.x - hand->state.position.x;
  const float dy = st.position.y - hand->state.position.y;
  const float dz = st.position.z - hand->state.position.z;
  if (!(std::sqrt(dx * dx + dy * dy + dz * dz) <= kMaxGrabPoseOffsetM)) {
    return refuse("the hand pose is more than 0.5 m from the hand's last state");
  }
  // The hand's state now, as ApplyStates takes an owner's state.
  if (hand->physics == PhysicsRole::kMirrored) TrackOwnerMotion(*hand, st, now);
  hand->state = st;
  ++hand->version;
  hand->changed_at = now;
  hand->state_time = now;
  if (hand->physics == PhysicsRole::kMirrored) room_.physics()->Drive(hand_id, st, now);
  ++grab_pose_stats_.applied;
  e->grab_requester = link.player_id();
  posed_grabs_.push_back({entity_id, hand_id});
}

void RoomHost::IssuePosedGrabs(int steps) {
  if (steps <= 0 || posed_grabs_.empty()) return;
  PhysicsLink* physics = room_.physics();
  std::vector<PosedGrab> waiting;
  for (PosedGrab& g : posed_grabs_) {
    g.steps_left -= steps;
    if (g.steps_left > 0) {
      waiting.push_back(g);
      continue;
    }
    // Still there (either may have been despawned while PhyS stepped): asked now, answered in
    // a later ApplyPhysics as a plain Grab.
    const Entity* e = room_.FindEntity(g.entity);
    if (physics != nullptr && e != nullptr && room_.FindEntity(g.hand) != nullptr) {
      physics->RequestGrab(g.entity, g.hand);
    }
  }
  posed_grabs_ = std::move(waiting);
}

}  // namespace edgephys
