#include "client/client_impl.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "client/client_endpoint.h"
#include "protocol/container_builder.h"
#include "protocol/emulation_codec.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/redirect.h"

namespace edgephys {
namespace {

// Most remote entities the table is pre-sized for from a RoomState (it grows past this freely).
constexpr size_t kMaxReservedEntities = 1 << 16;

// CLOCK_REALTIME in seconds: the clock of the kernel's receive timestamps.
double RealtimeNow() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec) + now.tv_nsec * 1e-9;
}

uint64_t UnixNowS() { return static_cast<uint64_t>(RealtimeNow()); }

}  // namespace

Client::Impl::Impl(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener)
    : config_(config),
      socket_(socket),
      listener_(listener != nullptr ? listener : &null_listener_),
      receive_buffer_(kMaxPacketSize + 512),
      payload_buffer_(kMaxUnreliablePayload) {
  batch_.states.reserve(64);
}

Status Client::Impl::Connect(const RelayAddress& address, std::span<const uint8_t> token,
                             double now) {
  if (state_ != ClientState::kIdle) {
    return Status::InvalidArgument("Connect() called twice");
  }
  Result<Endpoint> server = ToEndpoint(address);
  if (!server.ok()) return server.status();
  std::vector<Endpoint> relays;
  for (const RelayAddress& r : config_.relays) {
    Result<Endpoint> e = ToEndpoint(r);
    if (!e.ok()) return e.status();
    relays.push_back(*e);
  }
  relays_ = std::move(relays);
  server_ = *server;
  entry_server_ = *server;
  redirects_this_handshake_ = 0;
  token_.assign(token.begin(), token.end());
  nonce_ = SecureRandom64();
  Result<KeyExchange> kx = KeyExchange::Generate();
  if (!kx.ok()) return kx.status();
  key_exchange_ = std::make_unique<KeyExchange>(std::move(*kx));
  state_ = ClientState::kHandshaking;
  handshake_started_ = now;
  // false (no arrival times from this socket) is handled per datagram: Update() takes the time
  // of the read instead and counts it in arrival_time_fallbacks().
  if (config_.record_arrival_times) (void)socket_->EnableArrivalTimes();
  SendHandshake(now);
  return Status::Ok();
}

void Client::Impl::SendHandshake(double now) {
  last_handshake_send_ = now;
  flatbuffers::FlatBufferBuilder fbb(256);
  if (cookie_.empty()) {
    FinishControl(fbb, schema::CreateHello(fbb, nonce_));
    auto packet = BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize);
    // A lost Hello is like a lost datagram: Update() sends it again after handshake_resend_s.
    (void)socket_->SendTo(server_, packet);
  } else {
    if (key_exchange_ == nullptr) return;  // no key pair (generation failed): cannot Connect
    const KeyExchangePublic& key = key_exchange_->public_key();
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie_),
                                             fbb.CreateVector(token_), nonce_,
                                             fbb.CreateVector(key.data(), key.size())));
    auto packet = BuildHandshakePacket(PacketType::kConnect, fbb);
    // As for Hello: resent until answered.
    (void)socket_->SendTo(server_, packet);
  }
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

void Client::Impl::HandleHandshakePacket(std::span<const uint8_t> packet, double now) {
  if (state_ != ClientState::kHandshaking) return;
  PacketPrefix prefix{};
  DropReason reason{};
  ParsePacketPrefix(packet, &prefix, &reason);
  const auto* msg = VerifyControlMessage(packet.subspan(kPacketPrefixSize));
  if (msg == nullptr) return;
  if (prefix.type == PacketType::kChallenge && msg->body_type() == schema::Body::Challenge) {
    const auto* cookie = msg->body_as_Challenge()->cookie();
    if (cookie == nullptr || !cookie_.empty()) return;
    cookie_.assign(cookie->begin(), cookie->end());
    SendHandshake(now);
  } else if (prefix.type == PacketType::kAccept && msg->body_type() == schema::Body::Accept) {
    const auto* accept = msg->body_as_Accept();
    ConnectionConfig cc = config_.connection;
    if (accept->keepalive_ms() > 0) cc.keepalive_interval_s = accept->keepalive_ms() / 1000.0;
    if (accept->timeout_ms() > 0) cc.timeout_s = accept->timeout_ms() / 1000.0;
    const auto* relay_key = accept->relay_key();
    if (relay_key == nullptr && config_.require_packet_auth) {
      if (resuming_) return;  // as a Reject while resuming: try the next relay
      // A downgrade (or a relay without --packet-auth): refuse it, and tell the relay.
      std::vector<uint8_t> bye(kConnectionHeaderSize + 1, 0);
      WritePacketPrefix(PacketType::kDisconnect, accept->connection_id(), bye);
      bye.back() = static_cast<uint8_t>(DisconnectReason::kClientLeft);
      (void)socket_->SendTo(server_, bye);
      key_exchange_.reset();
      reject_reason_ = static_cast<uint16_t>(schema::RejectReason::AuthRequired);
      state_ = ClientState::kRejected;
      listener_->OnRejected(reject_reason_);
      return;
    }
    if (relay_key != nullptr) {
      Result<ConnectionKeys> keys = key_exchange_->Derive(
          std::span<const uint8_t>(relay_key->data(), relay_key->size()), /*own_is_client=*/true,
          token_, nonce_, accept->connection_id());
      if (!keys.ok()) return;  // not our relay's answer (a forged Accept): keep waiting
      seal_ = std::make_unique<PacketSeal>(*keys, PacketSeal::Side::kClient);
      seal_buffer_.resize(kMaxDatagramSize);
      open_buffer_.resize(kMaxDatagramSize);
    }
    key_exchange_.reset();
    connection_ = std::make_unique<Connection>(accept->connection_id(), cc, now);
    if (seal_) connection_->SetDatagramOverhead(kSealOverhead);  // count the sealed datagrams
    player_id_ = accept->player_id();
    state_ = ClientState::kConnected;
    if (resuming_) {  // transparent: rejoin the room at once
      (void)JoinRoom(resume_room_);
      return;
    }
    listener_->OnConnected(player_id_);
  } else if (prefix.type == PacketType::kReject && msg->body_type() == schema::Body::Redirect) {
    HandleRedirect(*msg, now);
  } else if (prefix.type == PacketType::kReject && msg->body_type() == schema::Body::Reject) {
    if (resuming_) return;  // e.g. a relay that does not know the room yet: try the next one
    reject_reason_ = static_cast<uint16_t>(msg->body_as_Reject()->reason());
    state_ = ClientState::kRejected;
    listener_->OnRejected(reject_reason_);
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
  properties_.clear();
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
  owned_[id] = owned;
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

Status Client::Impl::Grab(uint32_t entity_id, uint32_t hand_id) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateGrab(fbb, entity_id, hand_id));
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

void Client::Impl::RestartHandshake(const Endpoint& server, double now) {
  server_ = server;
  cookie_.clear();
  nonce_ = SecureRandom64();
  // A new handshake (a redirect, or a resume on another relay) agrees new packet keys: a fresh
  // key pair, and the previous connection's seal is dropped.
  seal_.reset();
  if (Result<KeyExchange> kx = KeyExchange::Generate(); kx.ok()) {
    key_exchange_ = std::make_unique<KeyExchange>(std::move(*kx));
  }
  handshake_started_ = now;
  state_ = ClientState::kHandshaking;
  SendHandshake(now);
}

void Client::Impl::HandleRedirect(const schema::ControlMessage& msg, double now) {
  auto ticket = ParseRedirect(*msg.body_as_Redirect());
  if (!ticket.ok() || redirects_this_handshake_ >= config_.max_redirects ||
      !VerifyRedirect(*ticket, token_, UnixNowS()).ok()) {
    ++redirects_refused_;  // forged, expired or a loop: keep waiting for a real answer
    return;
  }
  auto target = ParseEndpoint(ticket->address);
  if (!target.ok()) {
    ++redirects_refused_;
    return;
  }
  ++redirects_this_handshake_;
  ++redirects_followed_;
  RestartHandshake(*target, now);
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
        ResetRoom();
      }
      resuming_ = false;
      joined_ = true;
      room_ = j->room() ? j->room()->str() : std::string();
      entity_id_base_ = j->entity_id_base();
      state_format_ = j->state_format();
      if (!resumed) next_local_id_ = 1;
      if (!resumed) players_.clear();  // a new room: its members are announced afresh
      delta_decoder_.reset();
      shared_decoder_.reset();
      soft_decoder_.reset();
      position_step_m_ =
          j->position_step_m() > 0 ? j->position_step_m() : QuantizationConfig{}.position_step_m;
      if (j->state_format() == kDeltaStateFormat || j->state_format() == kSharedDeltaStateFormat) {
        QuantizationConfig q;
        q.position_step_m = j->position_step_m();
        q.rotation_error_deg = j->rotation_bound_deg();
        if (j->bounds_min() && j->bounds_max()) {
          q.bounds_min = {j->bounds_min()->x(), j->bounds_min()->y(), j->bounds_min()->z()};
          q.bounds_max = {j->bounds_max()->x(), j->bounds_max()->y(), j->bounds_max()->z()};
        }
        auto params = MakeQuantizationParams(q);
        if (params.ok() && j->state_format() == kSharedDeltaStateFormat) {
          shared_decoder_ = std::make_unique<SharedDeltaDecoder>(*params);
        } else if (params.ok()) {
          delta_decoder_ = std::make_unique<DeltaDecoder>(*params);
        }
      }
      if (resumed) {
        ++resumes_;
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
      if (delta_decoder_) delta_decoder_->Forget(id);
      if (shared_decoder_) shared_decoder_->Forget(id);
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
      listener_->OnError(static_cast<uint16_t>(e->reason()), e->entity_id(),
                         e->detail() ? e->detail()->string_view() : std::string_view());
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
  switch (payload[0]) {
    case kFormatPhoton:
    case kFormatPaper:
      return DecodeEmulationBatch(payload, &batch_, [this](uint32_t id, EntityState* s) {
        auto it = entities_.find(id);
        if (it == entities_.end()) return false;
        *s = it->second.state;
        return true;
      });
    case kDeltaStateFormat:
      batch_.states.clear();
      if (!delta_decoder_) return Status::Malformed("format 2 without quantisation");
      return delta_decoder_->Decode(payload, &batch_);
    case kSharedDeltaStateFormat:
      batch_.states.clear();
      if (!shared_decoder_) return Status(StatusCode::kMalformed, "format 9 without quantisation");
      return shared_decoder_->Decode(payload, &batch_);
    default:
      return DecodeStateBatch(payload, &batch_);
  }
}

void Client::Impl::OnUnreliablePayload(uint16_t /*sequence*/, std::span<const uint8_t> payload) {
  if (!joined_) {
    // Not decodable without the room's Joined (format, quantisation). The relay holds a
    // member's states until the member has acknowledged Joined, so these come only from a
    // room just left; the new room's stream never references them.
    ++state_payloads_outside_room_;
    return;
  }
  bytes_state_received_ += payload.size();
  if (!config_.decode_states) return;  // acknowledged by the connection all the same
  if (!payload.empty() && payload[0] == kSoftBodyFormat) {
    if (!joined_ || !DecodeSoftBodyChunk(payload, position_step_m_, kMaxSoftBodyNodes, &soft_chunk_).ok()) {
      return;
    }
    auto it = entities_.find(soft_chunk_.entity_id);
    if (it == entities_.end()) return;  // particles of an entity not spawned (yet): skip
    RemoteEntity& e = it->second;
    e.nodes.resize(soft_chunk_.total);
    std::copy(soft_chunk_.positions.begin(), soft_chunk_.positions.end(),
              e.nodes.begin() + soft_chunk_.first);
    listener_->OnSoftBodyUpdated(e);
    return;
  }
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
  if (!joined_ || !DecodeStates(payload).ok()) return;
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
