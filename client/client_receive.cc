// The client's receive side: reliable control messages from the relay (room state, spawns,
// ownership, properties, redirects, physics events) and unreliable state batches, decoded into
// the entity table and the listener's callbacks. The send side and the handshake are in
// client.cc.
#include "client/client_impl.h"

#include <algorithm>

#include "protocol/app_message_codec.h"
#include "client/state_decoder_plugin.h"
#include "protocol/handshake.h"

namespace edgephys {
namespace {

// Most remote entities the table is pre-sized for from a RoomState (it grows past this freely).
constexpr size_t kMaxReservedEntities = 1 << 16;

}  // namespace

void Client::Impl::OnReliableMessage(std::span<const uint8_t> message) {
  const auto* msg = VerifyControlMessage(message);
  if (msg == nullptr) return;  // a relay bug or a corrupted peer; nothing to apply
  switch (msg->body_type()) {
    case schema::Body::Joined: {
      const auto* j = msg->body_as_Joined();
      const bool resumed = resuming_ && j->room() != nullptr && j->room()->str() == resume_room_ &&
                           j->entity_id_base() == resume_base_;
      if (resumed) {
        // Same room, same id block: this player's entities are still its own. Forget what
        // the old relay sent; re-send every owned entity's state.
        auto owned = std::move(owned_);
        uint32_t next_local = next_local_id_;
        ResetRoom();
        owned_ = std::move(owned);
        for (auto& [id, e] : owned_) ++e.version;
        next_local_id_ = next_local;
      } else {
        if (resuming_) {
          // Back in another room or with another id block: the entities this player owned
          // are gone from its view; each is reported, none vanishes silently.
          std::vector<uint32_t> lost;
          for (const auto& [id, e] : owned_) lost.push_back(id);
          std::sort(lost.begin(), lost.end());
          for (uint32_t id : lost) {
            ReportLost(static_cast<uint16_t>(schema::RejectReason::NotOwner), id,
                       "the room came back without this player's id block");
          }
        }
        ResetRoom();
      }
      resuming_ = false;
      joined_ = true;
      room_ = j->room() ? j->room()->str() : std::string();
      entity_id_base_ = j->entity_id_base();
      state_format_ = j->state_format();
      if (!resumed) next_local_id_ = 1;
      if (!resumed) players_.clear();  // a new room: its members are announced afresh
      decoder_.reset();
      soft_decoder_.reset();
      position_step_m_ =
          j->position_step_m() > 0 ? j->position_step_m() : QuantizationConfig{}.position_step_m;
      QuantizationConfig q;
      q.position_step_m = j->position_step_m();
      q.rotation_error_deg = j->rotation_bound_deg();
      if (j->bounds_min() && j->bounds_max()) {
        q.bounds_min = {j->bounds_min()->x(), j->bounds_min()->y(), j->bounds_min()->z()};
        q.bounds_max = {j->bounds_max()->x(), j->bounds_max()->y(), j->bounds_max()->z()};
      }
      // A format the SDK does not decode (a plug-in's) may announce no quantisation at all.
      if (auto params = MakeQuantizationParams(q); params.ok()) {
        decoder_ = NewStateDecoder(state_format_, *params);
      }
      if (resumed) {
        ++resumes_;
        RespawnAfterResume();  // whatever the restored room lacks is spawned again
      } else {
        listener_->OnJoined(room_, entity_id_base_);
      }
      break;
    }
    case schema::Body::RoomState: {
      const auto* rs = msg->body_as_RoomState();
      // The members already in the room are announced like later joiners (once: a resume
      // that repeats the RoomState announces only the members new to this client).
      std::vector<uint32_t> known = std::move(players_);
      players_.clear();
      if (rs->players()) players_.assign(rs->players()->begin(), rs->players()->end());
      for (uint32_t p : players_) {
        if (p != player_id_ && std::find(known.begin(), known.end(), p) == known.end()) {
          listener_->OnPlayerJoined(p);
        }
      }
      // The spawns follow: size the table once rather than rehashing as they arrive (capped,
      // the count is only a hint from the network).
      entities_.reserve(std::min<size_t>(rs->entity_count(), kMaxReservedEntities));
      break;
    }
    case schema::Body::Spawn: {
      const auto* c = msg->body_as_Spawn()->container();
      if (c == nullptr || c->transform() == nullptr) return;
      // This player's own entity, as a relay that restored the room after a failover lists it.
      if (c->owner() == player_id_ && owned_.count(c->entity_id()) != 0) return;
      despawned_.erase(c->entity_id());
      RemoteEntity& e = entities_[c->entity_id()];
      e.id = c->entity_id();
      e.owner = c->owner();
      e.parent = c->parent_id();
      e.flags = c->flags();
      e.spawned = true;
      if (!e.has_state) {
        e.arrival_unix_s = packet_arrival_unix_s_;
        const auto* t = c->transform();
        e.state = {e.id,
                   {t->position().x(), t->position().y(), t->position().z()},
                   {t->rotation().x(), t->rotation().y(), t->rotation().z(), t->rotation().w()}};
      }
      listener_->OnEntitySpawned(e);
      break;
    }
    case schema::Body::Despawn: {
      uint32_t id = msg->body_as_Despawn()->entity_id();
      entities_.erase(id);
      if (decoder_) decoder_->Forget(id);
      if (soft_decoder_) soft_decoder_->Forget(id);
      despawned_.insert(id);
      ForgetEntityProperties(id);
      listener_->OnEntityDespawned(id);
      break;
    }
    case schema::Body::PlayerJoined: {
      uint32_t p = msg->body_as_PlayerJoined()->player_id();
      players_.push_back(p);
      listener_->OnPlayerJoined(p);
      break;
    }
    case schema::Body::PlayerLeft: {
      uint32_t p = msg->body_as_PlayerLeft()->player_id();
      std::erase(players_, p);
      listener_->OnPlayerLeft(p);
      break;
    }
    case schema::Body::PhysicsEvent: {
      const auto* ev = msg->body_as_PhysicsEvent();
      listener_->OnPhysicsEvent(static_cast<uint8_t>(ev->kind()), ev->entity_a(), ev->entity_b());
      break;
    }
    case schema::Body::Error: {
      const auto* e = msg->body_as_Error();
      const std::string_view detail = e->detail() ? e->detail()->string_view() : std::string_view();
      if (!respawned_.empty() &&
          RespawnRefused(static_cast<uint16_t>(e->reason()), e->entity_id(), detail)) {
        break;  // a resume's re-spawn: already in place, or reported lost
      }
      listener_->OnError(static_cast<uint16_t>(e->reason()), e->entity_id(), detail);
      break;
    }
    case schema::Body::AppMessage: {
      const auto* m = msg->body_as_AppMessage();
      std::span<const uint8_t> payload;
      if (m->payload() != nullptr) payload = {m->payload()->data(), m->payload()->size()};
      listener_->OnMessage(m->sender(), payload);
      break;
    }
    case schema::Body::PropertyChanged:
    case schema::Body::PropertyConflict: return OnPropertyMessage(*msg);
    case schema::Body::OwnershipChanged: return OnOwnershipChanged(*msg->body_as_OwnershipChanged());
    case schema::Body::Disconnecting: {
      const auto* d = msg->body_as_Disconnecting();
      disconnect_detail_ = d->detail() ? d->detail()->str() : std::string();
      break;
    }
    default:
      if (control_listener_ != nullptr) control_listener_->OnOtherMessage(*msg);
      break;
  }
}

Status Client::Impl::DecodeStates(std::span<const uint8_t> payload) {
  if (payload.empty()) return Status::Malformed("empty state payload");
  batch_.states.clear();
  if (payload[0] != state_format_) {
    return Status::Malformed("state format " + std::to_string(payload[0]) +
                             " in a room that announced format " + std::to_string(state_format_));
  }
  if (decoder_) return decoder_->Decode(payload, &batch_);
  if (config_.state_decoder == nullptr) {
    return Status::Malformed("state format " + std::to_string(payload[0]) +
                             " is not decoded by the SDK");
  }
  return config_.state_decoder->Decode(
      payload,
      [this](uint32_t id, EntityState* s) {
        auto it = entities_.find(id);
        if (it == entities_.end()) return false;
        *s = it->second.state;
        return true;
      },
      &batch_);
}

void Client::Impl::OnUnreliablePayload(uint16_t /*sequence*/, std::span<const uint8_t> payload) {
  if (!joined_) {
    // Not decodable without the room's Joined (format, quantisation). The relay holds a
    // member's states until the member has acknowledged Joined, so these come only from a
    // room just left; the new room's stream never references them.
    ++state_payloads_outside_room_;
    return;
  }
  if (!payload.empty() && payload[0] == kAppMessageFormat) return OnUnreliableMessage(payload);
  bytes_state_received_ += payload.size();
  if (!config_.decode_states) return;  // acknowledged by the connection all the same
  if (!payload.empty() && payload[0] == kSoftDeltaFormat) {
    // Decoded whatever the entity table holds: the relay counts this packet's versions as held
    // once it is acknowledged, so they must be stored even for a body not spawned yet.
    if (!soft_decoder_) {
      soft_decoder_ = std::make_unique<SoftDeltaReceiver>(position_step_m_, kMaxSoftBodyNodes);
    }
    (void)soft_decoder_->Decode(payload);  // malformed / undecodable records: counted, dropped
    for (const SoftDeltaUpdate& u : soft_decoder_->updates()) {
      auto it = entities_.find(u.id);
      if (it == entities_.end()) continue;
      RemoteEntity& e = it->second;
      const std::span<const Vec3f> shown = soft_decoder_->Display(u.id);
      e.nodes.resize(shown.size());
      std::copy(shown.begin() + u.first, shown.begin() + u.first + u.count, e.nodes.begin() + u.first);
      listener_->OnSoftBodyUpdated(e);
    }
    return;
  }
  if (!DecodeStates(payload).ok()) {
    ++state_payloads_refused_;
    return;
  }
  // One hash lookup per state in the common case (a known remote entity): own entities can only
  // have ids in this player's block, and an id in entities_ is never a tombstone (Spawn erases
  // the tombstone, Despawn erases the entity), so owned_ and despawned_ are consulted only for
  // ids in our block and for ids not seen yet.
  for (size_t i = 0; i < batch_.states.size(); ++i) {
    const EntityState& st = batch_.states[i];
    const uint32_t id = st.entity_id;
    if (!IsValidState(st)) continue;
    if (id - entity_id_base_ < kEntityIdBlock && owned_.count(id) != 0) continue;
    auto it = entities_.find(id);
    if (it == entities_.end()) {
      // Late states of an entity this client gained (outside its own block) are its own now.
      if (despawned_.count(id) != 0 || owned_.count(id) != 0) continue;
      it = entities_.try_emplace(id).first;
      it->second.id = id;
    }
    RemoteEntity& e = it->second;
    e.state = st;
    e.has_state = true;
    e.state_time_ms = batch_.time_ms;
    e.arrival_unix_s = packet_arrival_unix_s_;
    if (e.spawned) listener_->OnEntityUpdated(e);
  }
}

}  // namespace edgephys
