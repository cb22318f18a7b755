#include "client/client_impl.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "client/client_endpoint.h"
#include "protocol/container_builder.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"

namespace edgephys {
namespace {

// CLOCK_REALTIME in seconds: the clock of the kernel's receive timestamps.
double RealtimeNow() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec) + now.tv_nsec * 1e-9;
}

}  // namespace

Client::Impl::Impl(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener)
    : config_(config),
      socket_(socket),
      listener_(listener != nullptr ? listener : &null_listener_),
      receive_buffer_(kMaxPacketSize + 512),
      payload_buffer_(kMaxUnreliablePayload) {
  batch_.states.reserve(64);
}

void Client::Impl::Update(double now) {
  now_ = now;
  for (int i = 0; i < 4096; ++i) {
    Endpoint from;
    size_t n = 0;
    if (config_.record_arrival_times) {
      double arrival = 0;
      n = socket_->ReceiveFromTimed(&from, receive_buffer_, &arrival);
      if (n == 0) break;
      if (arrival <= 0) {
        arrival = RealtimeNow();
        ++arrival_time_fallbacks_;
      }
      packet_arrival_unix_s_ = arrival;
    } else {
      n = socket_->ReceiveFrom(&from, receive_buffer_);
      if (n == 0) break;
    }
    if (from != server_ || n > kMaxDatagramSize) continue;  // not our relay / oversized
    std::span<const uint8_t> packet(receive_buffer_.data(), n);
    PacketPrefix prefix{};
    DropReason reason{};
    if (!ParsePacketPrefix(packet.first(std::min(n, kMaxPacketSize)), &prefix, &reason)) continue;
    const bool data = prefix.type == PacketType::kData || prefix.type == PacketType::kDisconnect;
    if (data && seal_ != nullptr) {
      // Forged, corrupted or replayed packets are dropped before the connection sees them.
      const size_t opened = seal_->Open(packet, open_buffer_, &reason);
      if (opened == 0) {
        ++packets_refused_;
        continue;
      }
      packet = std::span<const uint8_t>(open_buffer_.data(), opened);
    } else if (n > kMaxPacketSize) {
      continue;  // only a sealed packet may be longer
    }
    if (data) {
      if (connection_ && prefix.connection_id == connection_->id() && connection_->connected()) {
        // An error either drops this one datagram (malformed, duplicate: nothing to undo) or
        // ends the connection, which the connected() check below reports.
        (void)connection_->ProcessPacket(packet, now, *this);
      }
    } else {
      HandleHandshakePacket(packet, now);
    }
  }

  if (state_ == ClientState::kHandshaking && resuming_) {
    if (now - resume_started_ > config_.resume_timeout_s) {
      resuming_ = false;
      state_ = ClientState::kDisconnected;
      disconnect_reason_ = DisconnectReason::kTimeout;
      ResetRoom();
      listener_->OnDisconnected(disconnect_reason_);
      return;
    }
    if (now - handshake_started_ > config_.resume_attempt_s) {
      // Next candidate: the first relay, then the configured ones, round robin.
      std::vector<Endpoint> candidates;
      if (entry_server_ != lost_server_) candidates.push_back(entry_server_);
      for (const Endpoint& e : relays_) {
        if (e != entry_server_ && e != lost_server_) candidates.push_back(e);
      }
      if (candidates.empty()) candidates.push_back(lost_server_);
      RestartHandshake(candidates[resume_index_++ % candidates.size()], now);
      redirects_this_handshake_ = 0;
      return;
    }
  }
  if (state_ == ClientState::kHandshaking) {
    if (now - handshake_started_ > config_.handshake_timeout_s) {
      state_ = ClientState::kFailed;
      return;
    }
    if (now - last_handshake_send_ >= config_.handshake_resend_s) SendHandshake(now);
    return;
  }
  if (state_ != ClientState::kConnected) return;
  // Reliable traffic (spawns) first, so a new entity's spawn leaves before its first state.
  connection_->Update(now, *this);
  if (!respawned_.empty()) ExpireRespawns(now);
  if (joined_ && connection_->connected() && now >= next_publish_) {
    Publish(now);
    next_publish_ = now + 1.0 / std::max(1.0, config_.publish_rate_hz);
  }
  if (!connection_->connected()) {
    DisconnectReason why = connection_->disconnect_reason();
    if (config_.resume && joined_ &&
        (why == DisconnectReason::kTimeout || why == DisconnectReason::kServerShutdown)) {
      return StartResume(now);
    }
    state_ = ClientState::kDisconnected;
    disconnect_reason_ = connection_->disconnect_reason();
    joined_ = false;
    listener_->OnDisconnected(disconnect_reason_);
  }
}

Status Client::Impl::JoinRoom(std::string_view room) {
  if (state_ != ClientState::kConnected) return Status::NotConnected("not connected");
  if (room.empty() || room.size() > kMaxRoomNameSize) {
    return Status::InvalidArgument("room name must be 1..64 bytes");
  }
  flatbuffers::FlatBufferBuilder fbb(128);
  FinishControl(fbb, schema::CreateJoinRoom(fbb, fbb.CreateString(room.data(), room.size())));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::LeaveRoom() {
  if (state_ != ClientState::kConnected) return Status::NotConnected("not connected");
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateLeaveRoom(fbb));
  Status st = connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
  ResetRoom();
  return st;
}

void Client::Impl::ResetRoom() {
  joined_ = false;
  room_.clear();
  entities_.clear();
  despawned_.clear();
  owned_.clear();
  respawned_.clear();
  properties_.clear();
  unreliable_.last.clear();
  players_.clear();
  tracker_ = ReplicationTracker();
}

Result<uint32_t> Client::Impl::Spawn(const SpawnDesc& desc) {
  if (state_ != ClientState::kConnected || !joined_) {
    return Status::NotConnected("join a room first");
  }
  EntityState st{0, desc.position, desc.rotation};
  if (!IsValidState(st)) return Status::InvalidArgument("transform not finite/unit");
  uint32_t id = 0;
  while (next_local_id_ < kEntityIdBlock) {
    uint32_t candidate = entity_id_base_ + next_local_id_++;
    if (owned_.count(candidate) == 0) {
      id = candidate;
      break;
    }
  }
  if (id == 0) return Status::ResourceExhausted("entity id block used up");
  st.entity_id = id;

  EntitySpec spec = desc;
  spec.id = id;
  spec.owner = player_id_;
  flatbuffers::FlatBufferBuilder fbb(512);
  auto container = AddContainer(fbb, spec);
  FinishControl(fbb, schema::CreateSpawn(fbb, container));
  if (fbb.GetSize() > config_.connection.max_message_size) {
    return Status::TooLarge("container larger than the reliable message limit");
  }
  Status sent = connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
  if (!sent.ok()) return sent;
  const bool offloaded = (desc.flags & static_cast<uint32_t>(schema::EntityFlags::Offloaded)) != 0;
  const bool dynamic = desc.rigid_body && !desc.rigid_body->kinematic && desc.rigid_body->mass > 0;
  if (offloaded && (dynamic || desc.soft_body)) {
    // PhyS will own it: its state comes back from the relay like any other entity's.
    return id;
  }
  // The spawn carries the initial transform: version 1 needs no state packet.
  OwnedEntity owned;
  owned.state = st;
  owned.parent = desc.parent_id;
  owned.flags = desc.flags;
  // Kept for a resume: a spawn queued into a connection that then died is sent again.
  owned.spawn.assign(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
  owned_[id] = std::move(owned);
  tracker_.MarkAcked(id, 1);
  return id;
}

Status Client::Impl::Despawn(uint32_t entity_id) {
  if (owned_.erase(entity_id) == 0) return Status::NotFound("not an owned entity");
  tracker_.Forget(entity_id);
  ForgetEntityProperties(entity_id);
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateDespawn(fbb, entity_id));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::Grab(uint32_t entity_id, uint32_t hand_id, const EntityState* hand_pose) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  flatbuffers::FlatBufferBuilder fbb(96);
  if (hand_pose == nullptr) {
    FinishControl(fbb, schema::CreateGrab(fbb, entity_id, hand_id));
  } else {
    const EntityState& h = *hand_pose;
    const schema::Pose pose(hand_id, schema::Vec3(h.position.x, h.position.y, h.position.z),
                            schema::Quat(h.rotation.x, h.rotation.y, h.rotation.z, h.rotation.w));
    FinishControl(fbb, schema::CreateGrab(fbb, entity_id, hand_id, &pose));
  }
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::Release(uint32_t entity_id) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateRelease(fbb, entity_id));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::PublishTransform(uint32_t entity_id, const Vec3f& position,
                                      const Quatf& rotation) {
  auto it = owned_.find(entity_id);
  if (it == owned_.end()) return Status::NotFound("not an owned entity");
  EntityState st{entity_id, position, rotation};
  if (!IsValidState(st)) return Status::InvalidArgument("transform not finite/unit");
  it->second.state = st;
  ++it->second.version;
  return Status::Ok();
}

void Client::Impl::Publish(double now) {
  if (owned_.empty()) return;
  const double resend_after = connection_->stats().rtt_s * 1.25 + 1.0 / config_.publish_rate_hz;
  const uint32_t time_ms = static_cast<uint32_t>(static_cast<uint64_t>(now * 1000.0));
  sent_scratch_.clear();
  auto flush = [&]() {
    size_t size = encoder_.Finish();
    if (size == 0) return;
    Result<uint16_t> seq = connection_->SendUnreliable({payload_buffer_.data(), size}, now, *this);
    if (seq.ok()) {
      for (const auto& [id, version] : sent_scratch_) tracker_.OnSent(*seq, id, version, now);
    }
    sent_scratch_.clear();
  };
  encoder_.Begin(payload_buffer_, time_ms);
  for (const auto& [id, e] : owned_) {
    if (!tracker_.NeedsSend(id, e.version, now, resend_after)) continue;
    if (!encoder_.Add(e.state)) {
      flush();
      encoder_.Begin(payload_buffer_, time_ms);
      encoder_.Add(e.state);
    }
    sent_scratch_.emplace_back(id, e.version);
  }
  flush();
}

Status Client::Impl::SendStateUnchecked(const EntityState& state, double now) {
  if (state_ != ClientState::kConnected) return Status::NotConnected("not connected");
  FloatStateEncoder encoder;
  encoder.Begin(payload_buffer_, static_cast<uint32_t>(static_cast<uint64_t>(now * 1000.0)));
  encoder.Add(state);
  size_t size = encoder.Finish();
  return connection_->SendUnreliable({payload_buffer_.data(), size}, now, *this).status();
}

Status Client::Impl::SendUnreliableRaw(std::span<const uint8_t> payload, double now) {
  if (state_ != ClientState::kConnected) return Status::NotConnected("not connected");
  return connection_->SendUnreliable(payload, now, *this).status();
}

Status Client::Impl::SendReliableUnchecked(std::span<const uint8_t> message) {
  if (state_ != ClientState::kConnected) return Status::NotConnected("not connected");
  return connection_->SendReliable(message);
}

void Client::Impl::StartResume(double now) {
  resuming_ = true;
  resume_room_ = room_;
  resume_base_ = entity_id_base_;
  resume_started_ = now;
  resume_index_ = 0;
  lost_server_ = server_;
  joined_ = false;
  connection_.reset();
  redirects_this_handshake_ = 0;
  // First the relay that was lost (a restart, or a blip), then the others (Update).
  RestartHandshake(server_, now);
}

void Client::Impl::Disconnect() {
  resuming_ = false;
  if (connection_ && connection_->connected()) {
    connection_->Disconnect(DisconnectReason::kClientLeft, *this);
  }
  if (state_ == ClientState::kConnected || state_ == ClientState::kHandshaking) {
    state_ = ClientState::kDisconnected;
    disconnect_reason_ = DisconnectReason::kClientLeft;
  }
  joined_ = false;
}

const ConnectionStats* Client::Impl::stats() const {
  return connection_ ? &connection_->stats() : nullptr;
}

const RemoteEntity* Client::Impl::FindEntity(uint32_t id) const {
  auto it = entities_.find(id);
  return it == entities_.end() ? nullptr : &it->second;
}

void Client::Impl::OnPacketAcked(uint16_t sequence) { tracker_.OnAcked(sequence); }

void Client::Impl::WritePacket(std::span<const uint8_t> packet) {
  if (seal_ != nullptr) {
    const size_t n = seal_->Seal(packet, seal_buffer_);
    if (n == 0) return;
    packet = std::span<const uint8_t>(seal_buffer_.data(), n);
  }
  // A refused send is a lost datagram (DatagramSocket::SendTo); the connection resends what
  // must arrive.
  (void)socket_->SendTo(server_, packet);
}

}  // namespace edgephys
