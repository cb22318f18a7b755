#include "relay/session.h"

#include "protocol/app_message_codec.h"
#include "protocol/handshake.h"
#include "relay/drop_log.h"
#include "relay/room_host.h"

namespace edgephys {

Session::Session(SessionHost* host, RelayCounters* counters, const Endpoint& endpoint,
                 uint32_t connection_id, uint32_t player_id, uint32_t permissions,
                 std::string token_room, uint64_t token_nonce, const ConnectionConfig& config,
                 const AbuseLimits& limits, double now)
    : host_(host),
      counters_(counters),
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
      connected_at_(now),
      reliable_capacity_(config.max_pending_reliable_bytes) {}

void Session::OnReliableMessage(std::span<const uint8_t> message) {
  using schema::Body;
  using schema::RejectReason;
  RelayCounters::Inc(counters_->reliable_messages_received);
  if (closing_) return;  // an operator is ending this connection
  const schema::ControlMessage* msg = VerifyControlMessage(message);
  if (msg == nullptr) return SendError(RejectReason::InvalidMessage, 0, "message failed verification");
  switch (msg->body_type()) {
    case Body::JoinRoom: {
      const auto* join = msg->body_as_JoinRoom();
      std::string_view room = join->room() ? join->room()->string_view() : std::string_view();
      return host_->OnJoinRoom(*this, room, now_);
    }
    case Body::LeaveRoom: return host_->OnLeaveRoom(*this, now_);
    case Body::WorkerHello: return host_->OnWorkerHello(*this);
    case Body::WorkerResult: return host_->OnWorkerResult(*this, *msg->body_as_WorkerResult());
    case Body::Spawn:
    case Body::Despawn:
    case Body::Grab:
    case Body::Release:
    case Body::AppMessage:
    case Body::PropertySet:
    case Body::OwnershipRequest: break;
    default: return SendError(RejectReason::InvalidMessage, 0, "unexpected message type");
  }
  // Requests about the joined room's entities.
  uint32_t entity = 0;
  if (msg->body_type() == Body::Despawn) entity = msg->body_as_Despawn()->entity_id();
  if (msg->body_type() == Body::Grab) entity = msg->body_as_Grab()->entity_id();
  if (msg->body_type() == Body::Release) entity = msg->body_as_Release()->entity_id();
  if (msg->body_type() == Body::PropertySet) entity = msg->body_as_PropertySet()->entity_id();
  if (msg->body_type() == Body::OwnershipRequest) {
    entity = msg->body_as_OwnershipRequest()->entity_id();
  }
  if (room_ == nullptr) return SendError(RejectReason::NotJoined, entity, "join a room first");
  switch (msg->body_type()) {
    case Body::Spawn: return room_->Spawn(*this, message, *msg->body_as_Spawn(), now_);
    case Body::Despawn: return room_->Despawn(*this, entity);
    case Body::Grab: {
      const schema::Grab& grab = *msg->body_as_Grab();
      if (grab.hand_pose() != nullptr) {
        return room_->GrabAt(*this, entity, grab.hand_id(), *grab.hand_pose(), now_);
      }
      return room_->Grab(*this, entity, grab.hand_id());
    }
    case Body::Release: return room_->Release(*this, entity, now_);
    case Body::AppMessage: return room_->Message(*this, *msg->body_as_AppMessage(), now_);
    case Body::PropertySet: return room_->SetProperty(*this, *msg->body_as_PropertySet(), now_);
    case Body::OwnershipRequest:
      return room_->Ownership(*this, *msg->body_as_OwnershipRequest(), now_);
    default: return;
  }
}

void Session::OnUnreliablePayload(uint16_t /*sequence*/, std::span<const uint8_t> payload) {
  if (closing_) return;
  if (is_worker_) return host_->OnWorkerStates(*this, payload);
  if (room_ == nullptr) return counters_->RejectUpdate(DropReason::kNotJoined);
  if (!payload.empty() && payload[0] == kAppMessageFormat) {
    // The channel delivers these in any order (protocol/connection.h); the client numbers
    // them 1, 2, ... per connection, and 0 is unnumbered. Short ones go on to be refused.
    if (payload.size() >= kAppMessageHeaderSize) {
      const uint32_t sequence = LoadU32LE(payload.data() + 10);
      if (sequence != 0) {
        if (sequence <= newest_message_sequence_) {
          return counters_->RejectUpdate(DropReason::kStale);
        }
        newest_message_sequence_ = sequence;
      }
    }
    return room_->MessageUnreliable(*this, payload, now_);
  }
  room_->ApplyStates(*this, payload, now_);
}

void Session::OnPacketAcked(uint16_t sequence) {
  if (replicator_) replicator_->OnPacketAcked(sequence);
}

void Session::EnableSeal(const ConnectionKeys& keys) {
  seal_ = std::make_unique<PacketSeal>(keys, PacketSeal::Side::kRelay);
  seal_buffer_.resize(kMaxDatagramSize);
  open_buffer_.resize(kMaxDatagramSize);
  connection().SetDatagramOverhead(kSealOverhead);  // its byte counts: the sealed datagrams
}

std::span<const uint8_t> Session::Open(std::span<const uint8_t> datagram, DropReason* reason) {
  const size_t n = seal_->Open(datagram, open_buffer_, reason);
  return {open_buffer_.data(), n};
}

void Session::WritePacket(std::span<const uint8_t> packet) {
  if (seal_ != nullptr) {  // runs on a pool thread in a parallel tick: the seal is this session's
    const size_t n = seal_->Seal(packet, seal_buffer_);
    if (n == 0) return;  // cannot happen for the connection's packets; a lost datagram if it did
    packet = {seal_buffer_.data(), n};
  }
  if (!buffering_) return host_->Transmit(endpoint_, packet);
  if (outbox_size_ == outbox_.size()) outbox_.emplace_back();
  outbox_[outbox_size_++].assign(packet.begin(), packet.end());
}

bool Session::SendReliable(std::span<const uint8_t> message) {
  ServiceSoon();
  if (connection_.SendReliable(message).ok()) return true;
  connection_.Disconnect(DisconnectReason::kReliableOverflow, *this);
  return false;
}

bool Session::SendUnreliable(std::span<const uint8_t> payload, double now) {
  if (!ReadyForStates()) return false;
  ServiceSoon();
  return connection_.SendUnreliable(payload, now, *this).ok();
}

void Session::SendError(schema::RejectReason reason, uint32_t entity_id, std::string_view detail) {
  counters_->RejectRequest(static_cast<uint16_t>(reason));
  // OverBudget names the budget (its detail, "over budget: <budget>"): one log line per budget.
  std::string name = schema::EnumNameRejectReason(reason);
  if (reason == schema::RejectReason::OverBudget) name += " (" + std::string(detail) + ")";
  DropLogOfThisThread().Note("request rejected", name, endpoint_, now_);
  flatbuffers::FlatBufferBuilder fbb(128);
  FinishControl(fbb, schema::CreateError(fbb, reason, entity_id,
                                         fbb.CreateString(detail.data(), detail.size())));
  (void)SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

void Session::BeginClose(DisconnectReason reason, std::string_view detail, double now) {
  if (closing_ || !connection_.connected()) return;
  if (detail.size() > kMaxCloseDetail) detail = detail.substr(0, kMaxCloseDetail);
  flatbuffers::FlatBufferBuilder fbb(64 + detail.size());
  FinishControl(fbb, schema::CreateDisconnecting(fbb, static_cast<schema::DisconnectReason>(reason),
                                                 fbb.CreateString(detail.data(), detail.size())));
  closing_ = true;
  close_reason_ = reason;
  close_deadline_ = now + kCloseGraceS;
  // Overflow disconnects at once (kReliableOverflow); otherwise wait for the acknowledgement.
  (void)SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
  close_acked_end_ = connection_.reliable_queued_end();
}

void Session::DropPayload(DropReason reason) {
  counters_->RejectPacket(reason);
  DropLogOfThisThread().Note("state payload dropped", DropReasonName(reason), endpoint_, now_);
}

void Session::DropUpdate(DropReason reason) {
  counters_->RejectUpdate(reason);
  DropLogOfThisThread().Note("entity update dropped", DropReasonName(reason), endpoint_, now_);
}

void Session::StartReplication(const ReplicationConfig& config) {
  replicator_ = std::make_unique<ClientReplicator>(config);
  states_after_reliable_ = connection_.reliable_queued_end();
}

bool Session::ReadyForStates() const {
  return connection_.connected() && replicator_ != nullptr &&
         connection_.reliable_acked_end() >= states_after_reliable_;
}

void Session::Replicate(const ReplicationFrame& frame, double now, RelayCounters& counters,
                        bool buffered) {
  buffering_ = buffered;
  ServiceSoon();
  replicator_->Tick(frame, player_id_, now, connection_, *this, counters);
}

void Session::FlushReplication() {
  buffering_ = false;
  if (due_at_flush_) {
    due_at_flush_ = false;
    host_->OnServiceSoon(*this);
  }
  for (size_t i = 0; i < outbox_size_; ++i) host_->Transmit(endpoint_, outbox_[i]);
  outbox_size_ = 0;
}

}  // namespace edgephys
