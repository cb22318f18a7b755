#include "relay/session.h"

#include "protocol/handshake.h"
#include "relay/relay.h"

namespace edgephys {

Session::Session(Relay* relay, const Endpoint& endpoint, uint32_t connection_id,
                 uint32_t player_id, uint32_t permissions, std::string token_room,
                 uint64_t token_nonce, const ConnectionConfig& config,
                 const AbuseLimits& limits, double now)
    : relay_(relay),
      endpoint_(endpoint),
      connection_(connection_id, config, now),
      player_id_(player_id),
      permissions_(permissions),
      token_room_(std::move(token_room)),
      token_nonce_(token_nonce),
      now_(now),
      packets_(limits.packets_per_s, limits.packets_per_s * 2),
      bytes_(limits.bytes_per_s, limits.bytes_per_s * 2),
      spawns_(limits.spawns_per_s, limits.spawns_per_s * 20),
      connected_at_(now) {}

void Session::OnReliableMessage(std::span<const uint8_t> message) {
  RelayCounters::Inc(relay_->counters_->reliable_messages_received);
  const schema::ControlMessage* msg = VerifyControlMessage(message);
  if (msg == nullptr) {
    relay_->SendError(*this, static_cast<uint16_t>(schema::RejectReason::InvalidMessage), 0,
                      "message failed verification");
    return;
  }
  switch (msg->body_type()) {
    case schema::Body::JoinRoom: {
      const auto* join = msg->body_as_JoinRoom();
      std::string_view room = join->room() ? join->room()->string_view() : std::string_view();
      relay_->OnJoinRoom(*this, room, now_);
      break;
    }
    case schema::Body::LeaveRoom:
      relay_->OnLeaveRoom(*this, now_);
      break;
    case schema::Body::Spawn:
      relay_->OnSpawn(*this, message, msg->body_as_Spawn());
      break;
    case schema::Body::Despawn:
      relay_->OnDespawn(*this, msg->body_as_Despawn()->entity_id());
      break;
    case schema::Body::Grab:
      relay_->OnGrab(*this, msg->body_as_Grab()->entity_id(), msg->body_as_Grab()->hand_id());
      break;
    case schema::Body::Release:
      relay_->OnRelease(*this, msg->body_as_Release()->entity_id());
      break;
    case schema::Body::WorkerHello:
      relay_->OnWorkerHello(*this);
      break;
    case schema::Body::WorkerResult:
      relay_->OnWorkerResult(*this, *msg->body_as_WorkerResult());
      break;
    default:
      relay_->SendError(*this, static_cast<uint16_t>(schema::RejectReason::InvalidMessage), 0,
                        "unexpected message type");
      break;
  }
}

void Session::OnUnreliablePayload(uint16_t /*sequence*/, std::span<const uint8_t> payload) {
  relay_->OnStates(*this, payload);
}

void Session::OnPacketAcked(uint16_t sequence) {
  if (replicator_) replicator_->OnPacketAcked(sequence);
}

void Session::WritePacket(std::span<const uint8_t> packet) {
  if (!buffering_) return relay_->Send(endpoint_, packet);
  if (outbox_size_ == outbox_.size()) outbox_.emplace_back();
  outbox_[outbox_size_++].assign(packet.begin(), packet.end());
}

void Session::FlushOutbox() {
  for (size_t i = 0; i < outbox_size_; ++i) relay_->Send(endpoint_, outbox_[i]);
  outbox_size_ = 0;
}

}  // namespace edgephys
