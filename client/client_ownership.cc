// Client ownership (client/client.h "Ownership", docs/protocol.md "Ownership"): requests, hand
// overs, releases and takeover settings, and the ownership changes the relay announces, which
// move an entity between the entities this client publishes and those it receives.
#include <flatbuffers/flatbuffers.h>

#include "client/client_impl.h"
#include "protocol/handshake.h"

namespace edgephys {

Status Client::Impl::SendOwnership(uint32_t entity_id, uint8_t action, uint32_t to_player,
                                   bool takeover_allowed) {
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateOwnershipRequest(fbb, entity_id,
                                                    static_cast<schema::OwnershipAction>(action),
                                                    to_player, takeover_allowed));
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

Status Client::Impl::ReleaseOwnership(uint32_t entity_id) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::Release), 0, false);
}

Status Client::Impl::SetTakeoverAllowed(uint32_t entity_id, bool allowed) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (owned_.count(entity_id) == 0) return Status::NotFound("not an owned entity");
  return SendOwnership(entity_id, static_cast<uint8_t>(schema::OwnershipAction::SetTakeover), 0,
                       allowed);
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
  if (mine != owned_.end() && owner != player_id_) {
    // Lost: stop publishing it; its states come from the relay from now on.
    RemoteEntity e;
    e.id = id;
    e.owner = owner;
    e.parent = mine->second.parent;
    e.flags = mine->second.flags;
    e.spawned = true;
    e.state = mine->second.state;
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
    o.state = e.state;
    o.state.entity_id = id;
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
Status Client::ReleaseOwnership(uint32_t entity_id) { return impl_->ReleaseOwnership(entity_id); }
Status Client::SetTakeoverAllowed(uint32_t entity_id, bool allowed) {
  return impl_->SetTakeoverAllowed(entity_id, allowed);
}
uint32_t Client::OwnerOf(uint32_t entity_id) const { return impl_->OwnerOf(entity_id); }
bool Client::Owns(uint32_t entity_id) const { return impl_->owned_.count(entity_id) != 0; }

}  // namespace edgephys
