// Client ownership (client/client.h "Ownership", docs/protocol.md "Ownership"): requests, hand
// overs, releases and takeover settings, and the ownership changes the relay announces, which
// move an entity between the entities this client publishes and those it receives.
#include <flatbuffers/flatbuffers.h>

#include <cmath>

#include "client/client_impl.h"
#include "protocol/handshake.h"

namespace edgephys {

Status Client::Impl::SendOwnership(uint32_t entity_id, uint8_t action, uint32_t to_player,
                                   bool takeover_allowed, const Vec3f& linear,
                                   const Vec3f& angular, uint8_t on_owner_leave) {
  flatbuffers::FlatBufferBuilder fbb(96);
  const schema::Vec3 lin(linear.x, linear.y, linear.z), ang(angular.x, angular.y, angular.z);
  // Velocities only when there are some (a Release of a moving body).
  const bool moving = linear.x != 0 || linear.y != 0 || linear.z != 0 || angular.x != 0 ||
                      angular.y != 0 || angular.z != 0;
  FinishControl(fbb, schema::CreateOwnershipRequest(fbb, entity_id,
                                                    static_cast<schema::OwnershipAction>(action),
                                                    to_player, takeover_allowed,
                                                    moving ? &lin : nullptr,
                                                    moving ? &ang : nullptr,
                                                    static_cast<schema::OwnerLeave>(on_owner_leave)));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::RequestOwnership(uint32_t entity_id) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0 && entities_.count(entity_id) == 0) {
    return Status::NotFound("no such entity in the room");
  }
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::Request), 0, false);
}

Status Client::Impl::HandOver(uint32_t entity_id, uint32_t player_id) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  if (player_id == 0 || player_id == player_id_) {
    return Status::InvalidArgument("hand over to another player (not 0, not this one)");
  }
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::HandOver),
                       player_id, false);
}

Status Client::Impl::ReleaseOwnership(uint32_t entity_id, const Vec3f& linear,
                                      const Vec3f& angular) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  for (float v : {linear.x, linear.y, linear.z, angular.x, angular.y, angular.z}) {
    if (!std::isfinite(v)) return Status::InvalidArgument("velocities must be finite");
  }
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::Release), 0, false,
                       linear, angular);
}

Status Client::Impl::SetTakeoverAllowed(uint32_t entity_id, bool allowed) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::SetTakeover), 0,
                       allowed);
}

Status Client::Impl::SetOwnerLeave(uint32_t entity_id, uint8_t choice) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (choice > static_cast<uint8_t>(schema::OwnerLeave::MAX)) {
    return Status::InvalidArgument("unknown owner-leave choice (0 default, 1 stay, 2 PhyS, 3 despawn)");
  }
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::SetOwnerLeave), 0,
                       false, {}, {}, choice);
}

uint32_t Client::Impl::OwnerOf(uint32_t entity_id) const {
  if (owned_.count(entity_id) != 0) return player_id_;
  const auto it = entities_.find(entity_id);
  return it == entities_.end() ? 0 : it->second.owner;
}

void Client::Impl::OnOwnershipChanged(const schema::OwnershipChanged& change) {
  const uint32_t id = change.entity_id();
  const uint32_t owner = change.owner();
  const uint32_t seq = change.authority_seq();
  auto mine = owned_.find(id);
  auto theirs = entities_.find(id);
  if (mine == owned_.end() && theirs == entities_.end()) return;  // unknown or despawned
  uint32_t& known_seq = mine != owned_.end() ? mine->second.authority_seq
                                             : theirs->second.authority_seq;
  bool& takeover = mine != owned_.end() ? mine->second.takeover_allowed
                                        : theirs->second.takeover_allowed;
  if (seq < known_seq) return;  // older news
  takeover = change.takeover_allowed();
  if (seq == known_seq) return;  // a takeover setting, or a repeat
  known_seq = seq;
  // The pose the relay held at the change (exact, not quantised) and the velocities of a switch
  // between local physics and PhyS (0 otherwise).
  const schema::Pose* pose = change.pose();
  const bool has_pose = pose != nullptr && pose->entity_id() == id;
  EntityState at{id, {}, {}};
  if (has_pose) {
    at.position = {pose->position().x(), pose->position().y(), pose->position().z()};
    at.rotation = {pose->rotation().x(), pose->rotation().y(), pose->rotation().z(),
                   pose->rotation().w()};
  }
  const bool pose_ok = has_pose && IsValidState(at);
  const auto velocity = [](const schema::Vec3* v) {
    return v != nullptr && std::isfinite(v->x()) && std::isfinite(v->y()) && std::isfinite(v->z())
               ? Vec3f{v->x(), v->y(), v->z()} : Vec3f{};
  };
  if (mine != owned_.end() && owner != player_id_) {
    // Lost: stop publishing it; its states come from the relay from now on.
    RemoteEntity e;
    e.id = id;
    e.owner = owner;
    e.parent = mine->second.parent;
    e.flags = mine->second.flags;
    e.spawned = true;
    e.state = pose_ok ? at : mine->second.state;
    e.authority_seq = seq;
    e.takeover_allowed = mine->second.takeover_allowed;
    owned_.erase(mine);
    tracker_.Forget(id);
    entities_[id] = std::move(e);
  } else if (theirs != entities_.end() && owner == player_id_) {
    // Gained: published from its last received state (at once: never acknowledged), until the
    // game moves it.
    const RemoteEntity& e = theirs->second;
    OwnedEntity o;
    o.state = pose_ok ? at : e.state;
    o.state.entity_id = id;
    o.linear_velocity = velocity(change.linear_velocity());
    o.angular_velocity = velocity(change.angular_velocity());
    o.version = 1;
    o.parent = e.parent;
    o.flags = e.flags;
    o.authority_seq = seq;
    o.takeover_allowed = e.takeover_allowed;
    tracker_.Forget(id);
    entities_.erase(theirs);
    owned_[id] = o;
  } else if (theirs != entities_.end()) {
    theirs->second.owner = owner;
  }
  listener_->OnOwnershipChanged(id, owner, seq);
}

Status Client::RequestOwnership(uint32_t entity_id) { return impl_->RequestOwnership(entity_id); }
Status Client::HandOver(uint32_t entity_id, uint32_t player_id) {
  return impl_->HandOver(entity_id, player_id);
}
Status Client::ReleaseOwnership(uint32_t entity_id, const Vec3f& linear, const Vec3f& angular) {
  return impl_->ReleaseOwnership(entity_id, linear, angular);
}
Status Client::OwnedMotion(uint32_t entity_id, EntityState* state, Vec3f* linear,
                           Vec3f* angular) const {
  const auto it = impl_->owned_.find(entity_id);
  if (it == impl_->owned_.end()) return Status::NotFound("not an owned entity");
  if (state != nullptr) *state = it->second.state;
  if (linear != nullptr) *linear = it->second.linear_velocity;
  if (angular != nullptr) *angular = it->second.angular_velocity;
  return Status::Ok();
}
Status Client::SetTakeoverAllowed(uint32_t entity_id, bool allowed) {
  return impl_->SetTakeoverAllowed(entity_id, allowed);
}
uint32_t Client::OwnerOf(uint32_t entity_id) const { return impl_->OwnerOf(entity_id); }
Status Client::SetOwnerLeave(uint32_t entity_id, uint8_t choice) {
  return impl_->SetOwnerLeave(entity_id, choice);
}
bool Client::Owns(uint32_t entity_id) const { return impl_->owned_.count(entity_id) != 0; }

}  // namespace edgephys
